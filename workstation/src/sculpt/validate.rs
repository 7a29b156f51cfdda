//! Value and reference checks of a parsed [`Script`], naming the offending field.

use std::collections::HashSet;

use glam::DVec3;

use super::script::{Op, Script, ScriptError, profile_of};
use crate::limits::{MAX_GEN_POINTS, MAX_STEPS, check};

fn err(field: impl Into<String>, reason: impl Into<String>) -> ScriptError {
    ScriptError {
        field: field.into(),
        reason: reason.into(),
    }
}

fn positive(field: String, x: f64) -> Result<(), ScriptError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be positive and finite (got {x})")))
    }
}

/// A count over its cap (see [`crate::limits`]), as a script error naming the field.
fn capped(
    field: String,
    value: usize,
    limit: usize,
    constant: &'static str,
    unit: &'static str,
) -> Result<(), ScriptError> {
    check(field, value, limit, unit, constant).map_err(|e| err(e.field.clone(), e.reason()))
}

fn finite3(field: String, v: [f64; 3]) -> Result<DVec3, ScriptError> {
    let d = DVec3::from_array(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(err(field, "must be finite"))
    }
}

impl Script {
    /// Check values and references.
    pub fn validate(&self) -> Result<(), ScriptError> {
        let mut names = HashSet::new();
        if self.object.is_empty() {
            return Err(err("object", "at least one [[object]] is required"));
        }
        for (i, o) in self.object.iter().enumerate() {
            let f = |x: &str| format!("object[{i}].{x}");
            if !names.insert(o.name.clone()) {
                return Err(err(
                    f("name"),
                    format!("duplicate object name `{}`", o.name),
                ));
            }
            finite3(f("offset"), o.offset)?;
            if let Some(size) = o.size {
                if o.file.is_none() {
                    return Err(err(
                        f("size"),
                        "scales a `file`; a generated shape has `generate.size`",
                    ));
                }
                positive(f("size"), size)?;
            }
            match (&o.file, &o.generate) {
                (Some(_), None) => {}
                (None, Some(g)) => {
                    let sampled = g.shape.starts_with("sample:");
                    if !["sphere", "torus", "plate", "box"].contains(&g.shape.as_str()) && !sampled
                    {
                        return Err(err(
                            f("generate.shape"),
                            "must be sphere, torus, plate, box or sample:MESH_FILE",
                        ));
                    }
                    positive(f("generate.size"), g.size)?;
                    if g.shape != "sphere" && !sampled {
                        positive(f("generate.size2"), g.size2)?;
                    }
                    if g.shape == "torus" && g.size2 >= g.size {
                        return Err(err(
                            f("generate.size2"),
                            "the torus tube radius must be smaller than `size`",
                        ));
                    }
                    if g.shape == "box" && g.size2 > g.size {
                        return Err(err(
                            f("generate.size2"),
                            "the box rounding must not exceed the half size `size`",
                        ));
                    }
                    if g.points < 50 {
                        return Err(err(f("generate.points"), "must be at least 50"));
                    }
                    capped(
                        f("generate.points"),
                        g.points,
                        MAX_GEN_POINTS,
                        "MAX_GEN_POINTS",
                        "points",
                    )?;
                }
                _ => return Err(err(f("file"), "give exactly one of `file` and `generate`")),
            }
        }
        let known = |field: String, name: &str, names: &HashSet<String>| {
            if names.contains(name) {
                Ok(())
            } else {
                Err(err(field, format!("no object named `{name}`")))
            }
        };
        if let Some(r) = &self.region {
            known("region.object".into(), &r.object, &names)?;
            let (lo, hi) = (
                finite3("region.min".into(), r.min)?,
                finite3("region.max".into(), r.max)?,
            );
            if !hi.cmpgt(lo).all() {
                return Err(err("region.max", "must exceed region.min on every axis"));
            }
            positive("region.spacing".into(), r.spacing)?;
            positive("region.band".into(), r.band)?;
            positive("region.dt".into(), r.dt)?;
            positive("region.accel_threshold".into(), r.accel_threshold)?;
            if let Some(g) = r.auto_upsample {
                positive("region.auto_upsample".into(), g)?;
            }
            if !["symplectic_euler", "forward_euler", "backward_euler"]
                .contains(&r.integrator.as_str())
            {
                return Err(err(
                    "region.integrator",
                    "must be symplectic_euler, forward_euler or backward_euler",
                ));
            }
            if let Some(n) = &r.node {
                n.validate()
                    .map_err(|e| err("region.node", e.to_string()))?;
            }
            let cells = ((hi - lo) / r.spacing).ceil();
            if cells.x * cells.y * cells.z > 2e7 {
                return Err(err("region.spacing", "gives more than 2·10⁷ grid nodes"));
            }
        }
        for (i, op) in self.op.iter().enumerate() {
            let f = |x: &str| format!("op[{i}].{x}");
            let needs_region = || {
                if self.region.is_some() {
                    Ok(())
                } else {
                    Err(err(format!("op[{i}]"), "needs a [region]"))
                }
            };
            match op {
                Op::Rope {
                    path,
                    path_end,
                    radius,
                    strength,
                    profile,
                    table,
                    sheet,
                    steps,
                    ..
                } => {
                    needs_region()?;
                    capped(f("steps"), *steps, MAX_STEPS, "MAX_STEPS", "steps")?;
                    if path.is_empty() {
                        return Err(err(f("path"), "needs at least one point"));
                    }
                    for (k, p) in path.iter().enumerate() {
                        finite3(f(&format!("path[{k}]")), *p)?;
                    }
                    if let Some(end) = path_end {
                        if end.len() != path.len() {
                            return Err(err(f("path_end"), "must have as many points as `path`"));
                        }
                        for (k, p) in end.iter().enumerate() {
                            finite3(f(&format!("path_end[{k}]")), *p)?;
                        }
                    }
                    positive(f("radius"), *radius)?;
                    if !strength.is_finite() {
                        return Err(err(f("strength"), "must be finite"));
                    }
                    profile_of(profile, table.as_deref()).map_err(|r| err(f("profile"), r))?;
                    if let Some(s) = sheet {
                        finite3(f("sheet"), *s)?;
                    }
                }
                Op::Relax { steps } => {
                    needs_region()?;
                    capped(f("steps"), *steps, MAX_STEPS, "MAX_STEPS", "steps")?;
                }
                Op::EndStroke => needs_region()?,
                Op::Paint {
                    object,
                    center,
                    force,
                    radius,
                    radius_per_newton,
                    max_radius,
                    falloff,
                    ..
                } => {
                    known(f("object"), object, &names)?;
                    finite3(f("center"), *center)?;
                    if !force.is_finite() {
                        return Err(err(f("force"), "must be finite"));
                    }
                    positive(f("radius"), *radius)?;
                    if !(radius_per_newton.is_finite() && *radius_per_newton >= 0.0) {
                        return Err(err(
                            f("radius_per_newton"),
                            format!("must be finite and ≥ 0 (got {radius_per_newton})"),
                        ));
                    }
                    if let Some(m) = max_radius {
                        positive(f("max_radius"), *m)?;
                    }
                    profile_of(falloff, None).map_err(|r| err(f("falloff"), r))?;
                }
                Op::Emboss {
                    object,
                    depth,
                    mapping,
                    ..
                } => {
                    known(f("object"), object, &names)?;
                    if !depth.is_finite() {
                        return Err(err(f("depth"), "must be finite"));
                    }
                    mapping
                        .validate()
                        .map_err(|e| err(f("mapping"), e.to_string()))?;
                }
                Op::Csg { a, b, result, .. } => {
                    known(f("a"), a, &names)?;
                    known(f("b"), b, &names)?;
                    if !names.insert(result.clone()) {
                        return Err(err(
                            f("result"),
                            format!("object `{result}` already exists"),
                        ));
                    }
                }
                Op::Upsample { object, max_gap } => {
                    known(f("object"), object, &names)?;
                    positive(f("max_gap"), *max_gap)?;
                }
                Op::Downsample {
                    object,
                    min_distance,
                } => {
                    known(f("object"), object, &names)?;
                    positive(f("min_distance"), *min_distance)?;
                }
            }
        }
        Ok(())
    }
}

//! One script operation at a time, on a [`Scene`].

use std::path::Path;

use anyhow::Context as _;
use glam::DVec3;
use sim_core::FitParams;
use sim_core::csg::{CsgOptions, Solid, csg};
use sim_core::resample::{UpsampleOptions, downsample, spacing, upsample};
use sim_core::scene::{Scene, SceneObject};
use sim_core::tools::Rope;
use sim_core::tools::emboss::{Emboss, GreyImage, detail_insertions, emboss};
use sim_core::tools::paint::{Brush, edge_insertions, paint};

use super::script::{Op, Release, profile_of};
use super::{fit_object, point_set};

fn solid_of(o: &SceneObject) -> Solid<'_> {
    Solid {
        positions: &o.positions,
        normals: &o.normals,
        colors: Some(&o.colors),
        field: &o.field,
    }
}

/// Run `op`; returns its kind and a one-line summary.
pub(crate) fn run_op(
    scene: &mut Scene,
    names: &mut Vec<String>,
    op: &Op,
    dt: f64,
    dir: &Path,
    fit: &FitParams,
) -> anyhow::Result<(&'static str, String)> {
    let id =
        |names: &[String], n: &str| names.iter().position(|x| x == n).context("unknown object");
    Ok(match op {
        Op::Rope {
            path,
            path_end,
            radius,
            strength,
            profile,
            table,
            sheet,
            steps,
            release,
        } => {
            let start: Vec<DVec3> = path.iter().map(|p| DVec3::from(*p)).collect();
            let end: Vec<DVec3> = path_end.as_ref().map_or(start.clone(), |e| {
                e.iter().map(|p| DVec3::from(*p)).collect()
            });
            let mut rope = Rope {
                path: start.clone(),
                radius: *radius,
                strength: *strength,
                profile: profile_of(profile, table.as_deref()).map_err(anyhow::Error::msg)?,
                sheet: sheet.map(DVec3::from),
            };
            let (mut residual, mut stranded, mut moved) = (0.0f64, 0usize, 0usize);
            for step in 0..*steps {
                let t = if *steps > 1 {
                    step as f64 / (*steps - 1) as f64
                } else {
                    1.0
                };
                for (k, p) in rope.path.iter_mut().enumerate() {
                    *p = start[k].lerp(end[k], t);
                }
                let r = scene.step(dt, std::slice::from_ref(&rope))?;
                residual = residual.max(r.follow.max_residual);
                stranded = stranded.max(r.follow.stranded);
                moved += r.follow.visited;
            }
            let released = match release {
                Release::Commit => format!(
                    "released: shape committed, {} local fields refitted",
                    scene.end_stroke()?
                ),
                Release::SpringBack => "released elastically".to_owned(),
            };
            (
                "rope",
                format!(
                    "{steps} steps; {moved} point updates; max residual {residual:.2e} m; {stranded} stranded; {released}"
                ),
            )
        }
        Op::Relax { steps } => {
            for _ in 0..*steps {
                scene.step(dt, &[])?;
            }
            ("relax", format!("{steps} steps"))
        }
        Op::EndStroke => (
            "end_stroke",
            format!("{} local fields refitted", scene.end_stroke()?),
        ),
        Op::Paint {
            object,
            center,
            force,
            color,
            radius,
            radius_per_newton,
            max_radius,
            falloff,
            clean_edges,
        } => {
            let oid = id(names, object)?;
            let brush = Brush {
                color: *color,
                radius: *radius,
                radius_per_newton: *radius_per_newton,
                max_radius: max_radius.unwrap_or(*radius),
                falloff: profile_of(falloff, None).map_err(anyhow::Error::msg)?,
            };
            let c = DVec3::from(*center);
            let mut added = 0;
            if *clean_edges {
                let o = &scene.objects()[oid];
                let h = spacing(&o.positions);
                let ins =
                    edge_insertions(&brush, c, *force, &o.positions, &o.normals, &o.field, h)?;
                added = ins.len();
                scene.insert_points(oid, &ins)?;
            }
            let o = scene.object_mut(oid).context("object")?;
            let rep = paint(&brush, c, *force, &o.positions, &mut o.colors)?;
            (
                "paint",
                format!(
                    "{} points painted (radius {:.4} m), {added} rim points added",
                    rep.painted, rep.radius
                ),
            )
        }
        Op::Emboss {
            object,
            image,
            mapping,
            depth,
        } => {
            let oid = id(names, object)?;
            let path = dir.join(image);
            let bytes =
                std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
            let op = Emboss {
                image: GreyImage::decode_png(&bytes)?,
                mapping: *mapping,
                depth: *depth,
            };
            let mut o = scene.objects()[oid].clone();
            // Points where the image has edges first, so the relief resolves them.
            let h = sim_core::resample::spacing(&o.positions);
            let added = detail_insertions(&op, &o.positions, &o.normals, &o.field, h)?;
            for a in &added {
                o.colors.push(o.colors[a.parent]);
                o.positions.push(a.position);
                o.normals.push(a.normal);
            }
            let moved = emboss(&op, &mut o.positions, &mut o.normals, &o.field, None)?;
            scene.replace_points(oid, point_set(&o), fit)?;
            (
                "emboss",
                format!(
                    "{moved} points displaced ({} added along the image's edges), field refitted",
                    added.len()
                ),
            )
        }
        Op::Csg { op, a, b, result } => {
            let (ia, ib) = (id(names, a)?, id(names, b)?);
            // Objects are found by name (scripts, shared scenes): a second of a name would hide.
            anyhow::ensure!(
                !names.contains(result),
                "the {op:?} of `{a}` and `{b}` would be named `{result}`, which an object is \
                 already called: give the result another name"
            );
            let (oa, ob) = (&scene.objects()[ia], &scene.objects()[ib]);
            let solid = solid_of;
            let (ps, rep) = csg(*op, solid(oa), solid(ob), &CsgOptions::default())?;
            anyhow::ensure!(
                !ps.positions.is_empty(),
                "the {op:?} of `{a}` and `{b}` is empty"
            );
            scene.add(fit_object(result.clone(), ps, fit)?);
            names.push(result.clone());
            (
                "csg",
                format!(
                    "{} + {} points kept, {} crease samples",
                    rep.kept_1, rep.kept_2, rep.edge_samples
                ),
            )
        }
        Op::Upsample { object, max_gap } => {
            let oid = id(names, object)?;
            let o = &scene.objects()[oid];
            let ins = upsample(
                &o.positions,
                &o.normals,
                &o.field,
                &UpsampleOptions {
                    max_gap: *max_gap,
                    k: 30,
                },
            );
            scene.insert_points(oid, &ins)?;
            scene.refit(oid, fit)?;
            ("upsample", format!("{} points inserted", ins.len()))
        }
        Op::Downsample {
            object,
            min_distance,
        } => {
            let oid = id(names, object)?;
            let o = &scene.objects()[oid];
            let before = o.positions.len();
            let merged = downsample(&point_set(o), &o.field, *min_distance);
            let after = merged.positions.len();
            scene.replace_points(oid, merged, fit)?;
            ("downsample", format!("{before} → {after} points"))
        }
    })
}

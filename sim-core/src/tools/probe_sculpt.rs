//! The shaped probe as a sculpting tool on the dynamic field (seed 004's ellipsoid probe,
//! applied to the point-set surface's sculpting region).
//!
//! The probe's implicit `f_p` (negative inside) gives an approximate signed distance
//! `ψ(x) = f_p / ‖∇f_p‖`. Each active node under the probe is pulled towards the field of a
//! Boolean of the material with the probe:
//! - **push** (carve, the probe enters from outside): `d → max(d, −ψ)`, the difference
//!   material ∖ probe; force `k · max(0, −ψ − d)` raises the value where the probe overlaps.
//! - **pull** (from inside, the probe drags material out as it leaves): `d → min(d, ψ)`, the
//!   union; force `k · min(0, ψ − d)` lowers the value where the probe reaches past the surface.
//!
//! Only nodes in the probe's bounding box are visited: O(nodes under the probe). The shape stays
//! once the stroke is committed ([`crate::scene::Scene::end_stroke`]).

use glam::DVec3;

use super::{GridTool, ToolError, positive};
use crate::dynamics::DynamicGrid;
use crate::probe::Probe;

/// Push (carve) or pull (extrude).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProbeMode {
    /// Carve: material leaves the probe.
    Push,
    /// Extrude: material fills the probe.
    Pull,
}

/// A posed probe pressing on the field.
#[derive(Debug, Clone)]
pub struct ProbeSculpt {
    /// The probe, posed where the tool is.
    pub probe: Probe,
    /// Push or pull.
    pub mode: ProbeMode,
    /// Force per metre of mismatch between a node's value and the Boolean's (N/m).
    pub stiffness: f64,
}

impl ProbeSculpt {
    /// Approximate signed distance to the probe surface (m, negative inside).
    pub fn distance(&self, x: DVec3) -> f64 {
        let f = self.probe.value(x);
        let g = self.probe.gradient(x).length();
        if g > 1e-12 {
            f / g
        } else {
            // The centre: half the smallest semi-axis inside, a safe under-estimate.
            -0.5 * self.probe.semi_axes().min_element()
        }
    }
}

impl GridTool for ProbeSculpt {
    fn apply(&self, model: &mut DynamicGrid) -> Result<usize, ToolError> {
        positive("stiffness", self.stiffness)?;
        let spec = *model.spec();
        let (lo, hi) = self.probe.aabb();
        let margin = DVec3::splat(spec.spacing);
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(ToolError::Param {
                name: "probe",
                reason: "must be posed at a finite position",
            });
        }
        let (a, b) = spec.node_range(lo - margin, hi + margin);
        let mut touched = 0;
        for k in a[2]..=b[2] {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    let g = spec.index(i, j, k);
                    let Some(s) = model.slot(g) else { continue };
                    let psi = self.distance(spec.node_position(i, j, k));
                    let d = model.value(g);
                    let gap = match self.mode {
                        ProbeMode::Push => (-psi - d).max(0.0),
                        ProbeMode::Pull => (psi - d).min(0.0),
                    };
                    if gap != 0.0 {
                        model.add_force(s, self.stiffness * gap);
                        touched += 1;
                    }
                }
            }
        }
        Ok(touched)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::NodeParams;
    use crate::grid::{GridSpec, ScalarGrid};
    use crate::probe::ProbePose;

    fn ball_model() -> DynamicGrid {
        let spec = GridSpec::covering(DVec3::splat(-0.03), DVec3::splat(0.03), 0.002);
        let rest = ScalarGrid::from_fn(spec, |p| p.length() - 0.02);
        DynamicGrid::new(&rest, 0.008, NodeParams::default()).unwrap()
    }

    fn tool(center: DVec3, mode: ProbeMode) -> ProbeSculpt {
        let probe = Probe::sphere(0.006)
            .unwrap()
            .posed(ProbePose::at(center))
            .unwrap();
        ProbeSculpt {
            probe,
            mode,
            stiffness: 1000.0,
        }
    }

    #[test]
    fn push_raises_values_under_the_probe_and_pull_lowers_them() {
        let mut m = ball_model();
        let n = tool(DVec3::new(0.0, 0.0, 0.022), ProbeMode::Push)
            .apply(&mut m)
            .unwrap();
        assert!(n > 0);
        assert!(m.forces().iter().all(|&f| f >= 0.0));
        assert!(m.forces().iter().any(|&f| f > 0.0));
        m.clear_forces();
        // Pulling from inside: the probe sits across the surface, material follows it out.
        let n = tool(DVec3::new(0.0, 0.0, 0.021), ProbeMode::Pull)
            .apply(&mut m)
            .unwrap();
        assert!(n > 0);
        assert!(m.forces().iter().all(|&f| f <= 0.0));
    }

    #[test]
    fn a_probe_far_from_the_surface_touches_nothing() {
        let mut m = ball_model();
        assert_eq!(
            tool(DVec3::new(0.0, 0.0, 0.5), ProbeMode::Push)
                .apply(&mut m)
                .unwrap(),
            0
        );
        assert_eq!(
            tool(DVec3::ZERO, ProbeMode::Pull).apply(&mut m).unwrap(),
            0,
            "deep inside, the material already fills the probe"
        );
    }
}

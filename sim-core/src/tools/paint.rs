//! Painting (000): a brush of colour `C_b` whose radius grows with the applied force, intensity
//! `I(r)` falling from 1 at the cursor to 0 at the brush radius (a [`Profile`]); each point
//! under the brush takes `C = C_b·I + C_p·(1 − I)` (in 8-bit sRGB, as the paper blends).
//!
//! Clean edges: a point whose footprint (a disc of half the sampling spacing) straddles the
//! brush rim is only partly under the brush; [`edge_insertions`] adds two points either side of
//! the rim on the zero set, so the painted boundary is resolved at a quarter of the spacing.
//!
//! Contract: zero force paints with the base radius; non-finite inputs are rejected; only points
//! within the brush radius change; deterministic.

use glam::DVec3;

use crate::field::GlobalField;
use crate::resample::Insertion;
use crate::tools::{Profile, ToolError, finite, positive};

/// A brush.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Brush {
    /// Paint colour `C_b` (sRGB).
    pub color: [u8; 3],
    /// Radius at zero force (m).
    pub radius: f64,
    /// Radius growth per newton of applied force (m/N).
    pub radius_per_newton: f64,
    /// Largest radius (m).
    pub max_radius: f64,
    /// Intensity falloff `I(r / R_b)`.
    pub falloff: Profile,
}

/// What a paint call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PaintReport {
    /// Points whose colour was blended.
    pub painted: usize,
    /// Brush radius used (m).
    pub radius: f64,
}

impl Brush {
    /// Check the parameters.
    pub fn validate(&self) -> Result<(), ToolError> {
        positive("radius", self.radius)?;
        finite("radius_per_newton", self.radius_per_newton)?;
        if self.radius_per_newton < 0.0 {
            return Err(ToolError::Param {
                name: "radius_per_newton",
                reason: "must be ≥ 0",
            });
        }
        positive("max_radius", self.max_radius)?;
        self.falloff.validate()
    }

    /// Radius for an applied force (its magnitude), clamped to `[radius, max_radius]`.
    pub fn radius_at(&self, force: f64) -> f64 {
        (self.radius + self.radius_per_newton * force.abs())
            .clamp(self.radius, self.max_radius.max(self.radius))
    }

    /// Intensity at distance `r` from the cursor for a brush of radius `radius`.
    pub fn intensity(&self, r: f64, radius: f64) -> f64 {
        self.falloff.weight(r / radius).clamp(0.0, 1.0)
    }
}

/// Blend the brush into `colors` for the points within reach of `center` under `force`.
pub fn paint(
    brush: &Brush,
    center: DVec3,
    force: f64,
    positions: &[DVec3],
    colors: &mut [[u8; 3]],
) -> Result<PaintReport, ToolError> {
    brush.validate()?;
    finite("force", force)?;
    if !center.is_finite() {
        return Err(ToolError::Param {
            name: "center",
            reason: "must be finite",
        });
    }
    let radius = brush.radius_at(force);
    let mut painted = 0;
    for (p, c) in positions.iter().zip(colors.iter_mut()) {
        let r = p.distance(center);
        if r >= radius {
            continue;
        }
        let i = brush.intensity(r, radius);
        *c = blend(brush.color, *c, i);
        painted += 1;
    }
    Ok(PaintReport { painted, radius })
}

/// `C_b·I + C_p·(1 − I)` per channel, rounded.
pub fn blend(brush: [u8; 3], paint: [u8; 3], intensity: f64) -> [u8; 3] {
    let i = intensity.clamp(0.0, 1.0);
    std::array::from_fn(|k| (brush[k] as f64 * i + paint[k] as f64 * (1.0 - i)).round() as u8)
}

/// Points to insert so the rim of a brush of radius `brush.radius_at(force)` is resolved: for
/// every point within `spacing/2` of the rim, two points at `±spacing/4` across it (along the
/// surface, radially from the cursor), projected onto `field`'s zero set.
pub fn edge_insertions(
    brush: &Brush,
    center: DVec3,
    force: f64,
    positions: &[DVec3],
    normals: &[DVec3],
    field: &GlobalField,
    spacing: f64,
) -> Result<Vec<Insertion>, ToolError> {
    brush.validate()?;
    finite("force", force)?;
    positive("spacing", spacing)?;
    let radius = brush.radius_at(force);
    let mut out = Vec::new();
    for (i, (&p, &n)) in positions.iter().zip(normals).enumerate() {
        let d = p - center;
        if (d.length() - radius).abs() >= 0.5 * spacing {
            continue;
        }
        let Some(radial) = (d - n * d.dot(n)).try_normalize() else {
            continue;
        };
        for s in [-0.25, 0.25] {
            let proj = field.project_to_zero_set(p + radial * (s * spacing));
            let (_, g) = field.value_and_gradient(proj.point);
            if let (true, Some(normal)) = (proj.converged && proj.trusted, g.try_normalize()) {
                out.push(Insertion {
                    position: proj.point,
                    normal,
                    parent: i,
                });
            }
        }
    }
    Ok(out)
}

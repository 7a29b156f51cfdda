//! The rope tool (000, Fig. 2): a force on the node values near a picked point or along a
//! curve, distributed by a radial profile. A positive `strength` pulls the surface outward
//! (it lowers values: force `−strength · w(dist/radius)` on each node), a negative one pushes in.
//!
//! At equilibrium under anchors `a` that dominate the neighbour springs, the surface rises by
//! `strength · w(r/radius) / (a ‖∇f‖)`: the bump *is* the profile (tested within tolerance).

use glam::DVec3;

use crate::dynamics::DynamicGrid;
use crate::grid::node_gradient;
use crate::tools::{ToolError, finite, positive};

/// Radial force profile `w(t)`, `t = r / radius`, with `w(0) = 1` and `w = 0` for `t ≥ 1`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", content = "table", rename_all = "snake_case")]
pub enum Profile {
    /// `exp(−t² / (2σ²))` with `σ = 1/3` (truncated at `t = 1`, where it is 0.011).
    Gaussian,
    /// `1` inside the radius.
    Constant,
    /// `√(1 − t²)`: a hemispherical cap.
    Spherical,
    /// User table: values at equally spaced `t = 0, 1/(n−1), …, 1`, linearly interpolated.
    Table(Vec<f64>),
}

impl Profile {
    /// The weight at `t = r / radius`.
    pub fn weight(&self, t: f64) -> f64 {
        if !(0.0..1.0).contains(&t) {
            return 0.0;
        }
        match self {
            Self::Gaussian => (-4.5 * t * t).exp(),
            Self::Constant => 1.0,
            Self::Spherical => (1.0 - t * t).sqrt(),
            Self::Table(v) => match v.len() {
                0 => 0.0,
                1 => v[0],
                n => {
                    let x = t * (n - 1) as f64;
                    let i = (x.floor() as usize).min(n - 2);
                    let a = x - i as f64;
                    v[i] * (1.0 - a) + v[i + 1] * a
                }
            },
        }
    }

    /// `Ok` when a table is non-empty and finite.
    pub fn validate(&self) -> Result<(), ToolError> {
        match self {
            Self::Table(v) if v.is_empty() || v.iter().any(|x| !x.is_finite()) => {
                Err(ToolError::Param {
                    name: "profile.table",
                    reason: "must be non-empty and finite",
                })
            }
            _ => Ok(()),
        }
    }
}

/// A rope attached at one point (`path.len() == 1`) or along a polyline.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rope {
    /// Attachment point, or the polyline of a curve rope.
    pub path: Vec<DVec3>,
    /// Reach of the profile (m).
    pub radius: f64,
    /// Peak force on a node (N); positive pulls the surface outward.
    pub strength: f64,
    /// Force distribution.
    pub profile: Profile,
    /// The picked sheet's outward normal: when set, each node's force is scaled by
    /// `max(0, n̂·∇d⁰/‖∇d⁰‖)`, so on a thin shell only the picked sheet's side of the slab is
    /// pulled (nodes nearer the other sheet have the opposite rest gradient). `None`: all nodes.
    #[serde(default)]
    pub sheet: Option<DVec3>,
}

impl Rope {
    /// Check the parameters.
    pub fn validate(&self) -> Result<(), ToolError> {
        if self.path.is_empty() || self.path.iter().any(|p| !p.is_finite()) {
            return Err(ToolError::Param {
                name: "path",
                reason: "must hold at least one finite point",
            });
        }
        positive("radius", self.radius)?;
        finite("strength", self.strength)?;
        if self.sheet.is_some_and(|n| n.try_normalize().is_none()) {
            return Err(ToolError::Param {
                name: "sheet",
                reason: "must be a finite non-zero vector",
            });
        }
        self.profile.validate()
    }

    /// Distance from `x` to the rope's path.
    pub fn distance(&self, x: DVec3) -> f64 {
        if self.path.len() == 1 {
            return x.distance(self.path[0]);
        }
        self.path
            .windows(2)
            .map(|s| {
                let (a, b) = (s[0], s[1]);
                let ab = b - a;
                let t = if ab.length_squared() > 0.0 {
                    ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                x.distance(a + ab * t)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Add the rope's forces to the active nodes within reach; returns how many were touched.
    /// Cost: O(grid nodes in the path's bounding box ± radius).
    pub fn apply(&self, model: &mut DynamicGrid) -> Result<usize, ToolError> {
        self.validate()?;
        let spec = *model.spec();
        let (mut lo, mut hi) = (self.path[0], self.path[0]);
        for &p in &self.path {
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        let r = DVec3::splat(self.radius);
        let (a, b) = spec.node_range(lo - r, hi + r);
        let mut touched = 0;
        for k in a[2]..=b[2] {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    let Some(s) = model.slot(spec.index(i, j, k)) else {
                        continue;
                    };
                    let mut w = self
                        .profile
                        .weight(self.distance(spec.node_position(i, j, k)) / self.radius);
                    if let (Some(n), true) = (self.sheet, w != 0.0) {
                        let g = node_gradient(&spec, model.rest_values(), i, j, k);
                        w *= g
                            .try_normalize()
                            .map_or(0.0, |g| g.dot(n.normalize()).max(0.0));
                    }
                    if w != 0.0 {
                        model.add_force(s, -self.strength * w);
                        touched += 1;
                    }
                }
            }
        }
        Ok(touched)
    }
}

//! The point set a surface is fitted to: positions, optional unit normals, optional colours.
//!
//! Contract: a `PointSet` that passed [`PointSet::validate`] has only finite coordinates and
//! per-point arrays of matching length; a normal of zero length means "unknown, estimate it".

use glam::DVec3;

/// Points with optional per-point normals and RGB colours.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointSet {
    /// Positions in metres.
    pub positions: Vec<DVec3>,
    /// Outward unit normals, one per point, or `None` when the source had none.
    pub normals: Option<Vec<DVec3>>,
    /// 8-bit sRGB colours, one per point, or `None`.
    pub colors: Option<Vec<[u8; 3]>>,
}

/// Why a point set cannot be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PointSetError {
    /// There are no points.
    #[error("the point set is empty")]
    Empty,
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the offending point.
        index: usize,
    },
    /// A per-point array has a different length from the positions.
    #[error("{what} has {got} entries for {expected} points")]
    Length {
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// Number of points.
        expected: usize,
    },
}

impl PointSet {
    /// Points without normals or colours.
    pub fn from_positions(positions: Vec<DVec3>) -> Self {
        Self {
            positions,
            normals: None,
            colors: None,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// `true` when there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Check lengths and finiteness; non-finite or zero normals are replaced by zero (unknown)
    /// and the others normalised, so a validated set can be fitted.
    pub fn validate(&mut self) -> Result<(), PointSetError> {
        if self.positions.is_empty() {
            return Err(PointSetError::Empty);
        }
        let n = self.positions.len();
        if let Some(index) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(PointSetError::NonFinite { index });
        }
        if let Some(normals) = &mut self.normals {
            if normals.len() != n {
                return Err(PointSetError::Length {
                    what: "normals",
                    got: normals.len(),
                    expected: n,
                });
            }
            for nrm in normals.iter_mut() {
                *nrm = nrm.try_normalize().unwrap_or(DVec3::ZERO);
            }
        }
        if let Some(colors) = &self.colors
            && colors.len() != n
        {
            return Err(PointSetError::Length {
                what: "colors",
                got: colors.len(),
                expected: n,
            });
        }
        Ok(())
    }

    /// Axis-aligned bounding box `(min, max)`; `None` when empty.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        bounds(&self.positions)
    }
}

/// Axis-aligned bounding box of `points`; `None` when empty.
pub fn bounds(points: &[DVec3]) -> Option<(DVec3, DVec3)> {
    let first = *points.first()?;
    Some(
        points
            .iter()
            .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
    )
}

//! The point set a surface is fitted to: positions, optional unit normals, optional colours.
//!
//! Contract: a `PointSet` that passed [`PointSet::validate`] has only finite coordinates and
//! per-point arrays of matching length; a normal of zero length means "unknown, estimate it".

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

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

    /// Merge points at one position (bit for bit, +0 and −0 alike) into the first of them, in
    /// order, unless their normals face apart (the two sides of a sheet of no thickness stay
    /// two points). A mesh file repeats a vertex where its normals or texture split; two samples
    /// at one place are two particles to a sculpting region and halve the neighbourhood a fit
    /// sees. The kept point's normal is the mean of the copies' directions, its colour the
    /// first's. Returns how many points were merged away.
    pub fn merge_coincident(&mut self) -> usize {
        let n = self.positions.len();
        let mut first: HashMap<[u64; 3], usize> = HashMap::with_capacity(n);
        let mut into: Vec<usize> = (0..n).collect();
        for i in 0..n {
            let j = *first.entry(position_key(self.positions[i])).or_insert(i);
            let agree = self
                .normals
                .as_ref()
                .is_none_or(|ns| ns[i].dot(ns[j]) >= 0.0);
            if j != i && agree {
                into[i] = j;
            }
        }
        let kept: Vec<usize> = (0..n).filter(|&i| into[i] == i).collect();
        if kept.len() == n {
            return 0;
        }
        if let Some(ns) = &mut self.normals {
            let mut sum = vec![DVec3::ZERO; n];
            for (i, &j) in into.iter().enumerate() {
                sum[j] += ns[i].try_normalize().unwrap_or(DVec3::ZERO);
            }
            *ns = kept
                .iter()
                .map(|&i| sum[i].try_normalize().unwrap_or(DVec3::ZERO))
                .collect();
        }
        if let Some(cs) = &mut self.colors {
            *cs = kept.iter().map(|&i| cs[i]).collect();
        }
        self.positions = kept.iter().map(|&i| self.positions[i]).collect();
        n - kept.len()
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

/// Indices of `points` sorted along a Morton (Z-order) curve over their bounding box (21 bits
/// per axis), so points near each other in space sit near each other in the order.
pub fn morton_order(points: &[DVec3]) -> Vec<u32> {
    let (lo, hi) = bounds(points).unwrap_or((DVec3::ZERO, DVec3::ONE));
    let scale = ((1u64 << 21) - 1) as f64 / (hi - lo).max_element().max(f64::MIN_POSITIVE);
    let spread = |v: f64| -> u64 {
        let mut x = (v.clamp(0.0, ((1u64 << 21) - 1) as f64)) as u64;
        x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = (*p - lo) * scale;
            (
                spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2),
                i as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// A position's key for finding exact repeats: its coordinates' bits, with −0 made +0.
pub fn position_key(p: DVec3) -> [u64; 3] {
    (p + DVec3::ZERO).to_array().map(f64::to_bits)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_repeated_at_one_position_merge_unless_they_face_apart() {
        let ring: Vec<DVec3> = (0..6)
            .map(|k| DVec3::new((k as f64).cos(), (k as f64).sin(), 0.0))
            .collect();
        // Every point twice (the second copy tilted, as a mesh's split normals are), the
        // first once more as −0 where it is 0, and one copy facing the other way.
        let tilt = |n: DVec3| (n + DVec3::Z * 0.2).normalize();
        let mut positions: Vec<DVec3> = ring.iter().chain(&ring).copied().collect();
        let mut normals: Vec<DVec3> = ring
            .iter()
            .copied()
            .chain(ring.iter().map(|&n| tilt(n)))
            .collect();
        positions.push(ring[1] * DVec3::new(1.0, 1.0, -1.0)); // z = −0
        normals.push(ring[1]);
        positions.push(ring[2]);
        normals.push(-ring[2]);
        let mut colors: Vec<[u8; 3]> = (0..positions.len() as u8).map(|i| [i, 0, 0]).collect();
        colors[0] = [9, 9, 9];
        let mut set = PointSet {
            positions,
            normals: Some(normals),
            colors: Some(colors),
        };
        assert_eq!(set.merge_coincident(), 7);
        let mut want = ring.clone();
        want.push(ring[2]);
        assert_eq!(
            set.positions, want,
            "the first of each, in order; the opposite one kept"
        );
        let normals = set.normals.as_ref().unwrap();
        assert!((normals[0] - (ring[0] + tilt(ring[0])).normalize()).length() < 1e-12);
        let three = ring[1] * 2.0 + tilt(ring[1]);
        assert!((normals[1] - three.normalize()).length() < 1e-12, "−0 is 0");
        assert_eq!(normals[6], -ring[2]);
        assert_eq!(
            set.colors.as_ref().unwrap()[0],
            [9, 9, 9],
            "the first's colour"
        );
        // Without normals every repeat merges; without repeats nothing changes.
        let mut bare = PointSet::from_positions(vec![DVec3::X, DVec3::Y, DVec3::X]);
        assert_eq!(bare.merge_coincident(), 1);
        assert_eq!(bare.positions, vec![DVec3::X, DVec3::Y]);
        assert_eq!(bare.merge_coincident(), 0);
    }

    #[test]
    fn morton_order_is_a_permutation_that_keeps_neighbours_together() {
        assert!(morton_order(&[]).is_empty());
        // A 4×4×4 lattice, shuffled: the order visits each 2×2×2 octant's eight points in one
        // run, and every point once.
        let mut points: Vec<DVec3> = (0..64)
            .map(|i| DVec3::new((i % 4) as f64, ((i / 4) % 4) as f64, (i / 16) as f64))
            .collect();
        points.reverse();
        points.swap(3, 40);
        let order = morton_order(&points);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..64).collect::<Vec<u32>>());
        for run in order.chunks(8) {
            let octant = |i: u32| (points[i as usize] / 2.0).floor();
            assert!(run.iter().all(|&i| octant(i) == octant(run[0])), "{run:?}");
        }
        // Along a line, the order is the line's.
        let line: Vec<DVec3> = [3.0, 0.5, 2.0, 1.0]
            .map(|x| DVec3::new(x, 0.0, 0.0))
            .to_vec();
        assert_eq!(morton_order(&line), vec![1, 3, 2, 0]);
    }
}

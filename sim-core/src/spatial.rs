//! A multi-level hash grid over spherical supports (centre, radius): "which supports contain x?"
//! in O(supports near x), independent of the point count.
//!
//! Level `l` has cells of edge `base·2ˡ`; a support is stored once, in the cell holding its
//! centre, on the finest level whose edge is at least twice its radius. A query then visits the
//! 2×2×2 cells around `x` on each non-empty level. Contract: immutable after
//! construction; queries do not allocate.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

/// Index of spherical supports.
#[derive(Debug, Clone)]
pub struct SupportGrid {
    base: f64,
    origin: DVec3,
    levels: Vec<Level>,
}

#[derive(Debug, Clone, Default)]
struct Level {
    cell: f64,
    /// Cell key → range into `items`.
    cells: HashMap<u64, (u32, u32), BuildHasherDefault<MulHasher>>,
    /// Supports sorted by cell, with their centre and squared radius inline so the distance
    /// test reads contiguous memory.
    items: Vec<SupportItem>,
    /// Supports added after construction ([`SupportGrid::insert`]), by cell key; visited
    /// after a cell's sorted items.
    added: HashMap<u64, Vec<SupportItem>, BuildHasherDefault<MulHasher>>,
}

impl Level {
    /// The supports stored in cell `k`: the sorted ones, then the added ones (two slices, so
    /// the hot loop over the first stays a plain slice loop).
    #[inline]
    fn cell(&self, k: u64) -> [&[SupportItem]; 2] {
        let sorted = match self.cells.get(&k) {
            Some(&(s, e)) => &self.items[s as usize..e as usize],
            None => &[][..],
        };
        let added = if self.added.is_empty() {
            &[][..]
        } else {
            self.added.get(&k).map_or(&[][..], Vec::as_slice)
        };
        [sorted, added]
    }

    fn is_empty(&self) -> bool {
        self.items.is_empty() && self.added.is_empty()
    }
}

/// One stored support: centre, squared radius, id.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SupportItem {
    pub(crate) center: DVec3,
    pub(crate) radius2: f64,
    pub(crate) id: u32,
}

impl SupportItem {
    /// Whether the support's ball reaches into the box `[lo, hi]`.
    #[inline]
    pub(crate) fn reaches_box(&self, lo: DVec3, hi: DVec3) -> bool {
        let gap = (lo - self.center).max(self.center - hi).max(DVec3::ZERO);
        gap.length_squared() < self.radius2
    }
}

impl SupportGrid {
    /// Index supports `i` with `radius[i] > 0` (others are never reported). `base` > 0 is the
    /// finest cell edge; choose about twice the typical radius.
    pub fn new(centers: &[DVec3], radius: &[f64], base: f64) -> Self {
        let base = if base > 0.0 && base.is_finite() {
            base
        } else {
            1.0
        };
        let origin = crate::pointset::bounds(centers).map_or(DVec3::ZERO, |(lo, _)| lo);
        let level_of = |r: f64| -> usize {
            let ratio = (2.0 * r / base).max(1.0);
            (ratio.log2().ceil() as usize).min(60)
        };
        let nlevels = radius
            .iter()
            .filter(|r| **r > 0.0)
            .map(|r| level_of(*r) + 1)
            .max()
            .unwrap_or(0);
        let mut keyed: Vec<Vec<(u64, u32)>> = vec![Vec::new(); nlevels];
        for (i, (&c, &r)) in centers.iter().zip(radius).enumerate() {
            if r > 0.0 && r.is_finite() {
                let l = level_of(r);
                let cell = base * (1u64 << l) as f64;
                keyed[l].push((key(cell_of(c - origin, cell)), i as u32));
            }
        }
        let levels = keyed
            .into_iter()
            .enumerate()
            .map(|(l, mut list)| {
                list.sort_unstable();
                let mut level = Level {
                    cell: base * (1u64 << l) as f64,
                    ..Level::default()
                };
                let mut start = 0;
                while start < list.len() {
                    let k = list[start].0;
                    let end = start + list[start..].iter().take_while(|e| e.0 == k).count();
                    level.cells.insert(k, (start as u32, end as u32));
                    start = end;
                }
                level.items = list
                    .into_iter()
                    .map(|(_, i)| SupportItem {
                        center: centers[i as usize],
                        radius2: radius[i as usize] * radius[i as usize],
                        id: i,
                    })
                    .collect();
                level
            })
            .collect();
        Self {
            base,
            origin,
            levels,
        }
    }

    /// Finest cell edge.
    pub fn base(&self) -> f64 {
        self.base
    }

    /// Add support `id` (ball of `radius` at `center`) after construction: found by every query
    /// from now on, after the supports the grid was built with in the same cell. A support
    /// larger than any level so far gets its level. Amortised O(1).
    pub fn insert(&mut self, center: DVec3, radius: f64, id: u32) {
        if !(radius > 0.0 && radius.is_finite() && center.is_finite()) {
            return;
        }
        let ratio = (2.0 * radius / self.base).max(1.0);
        let l = (ratio.log2().ceil() as usize).min(60);
        while self.levels.len() <= l {
            let cell = self.base * (1u64 << self.levels.len()) as f64;
            self.levels.push(Level {
                cell,
                ..Level::default()
            });
        }
        let level = &mut self.levels[l];
        let k = key(cell_of(center - self.origin, level.cell));
        level.added.entry(k).or_default().push(SupportItem {
            center,
            radius2: radius * radius,
            id,
        });
    }

    /// Call `visit(i, x − cᵢ, |x − cᵢ|²)` for every stored support `i` that contains `x`
    /// (`|x − cᵢ| < rᵢ`). Allocation-free.
    #[inline]
    pub fn for_each_containing(&self, x: DVec3, mut visit: impl FnMut(usize, DVec3, f64)) {
        let rel = x - self.origin;
        for level in &self.levels {
            if level.is_empty() {
                continue;
            }
            let f = rel / level.cell;
            let lo = (f - DVec3::splat(0.5)).floor();
            if !lo.is_finite() || lo.abs().max_element() > 1e15 {
                continue;
            }
            let lo = lo.as_i64vec3();
            for dz in 0..2 {
                for dy in 0..2 {
                    for dx in 0..2 {
                        let k = key([lo.x + dx, lo.y + dy, lo.z + dz]);
                        for items in level.cell(k) {
                            for item in items {
                                let rel = x - item.center;
                                let dist2 = rel.length_squared();
                                if dist2 < item.radius2 {
                                    visit(item.id as usize, rel, dist2);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

impl SupportGrid {
    /// Replace `out` by every support whose ball reaches into the box `[lo, hi]`, in the order
    /// [`SupportGrid::for_each_containing`] would meet them.
    pub(crate) fn gather_box(&self, lo: DVec3, hi: DVec3, out: &mut Vec<SupportItem>) {
        out.clear();
        for level in &self.levels {
            if level.is_empty() {
                continue;
            }
            // A support lives in its centre's cell, and its radius is at most half a cell.
            let first = ((lo - self.origin) / level.cell - DVec3::splat(0.5)).floor();
            let last = ((hi - self.origin) / level.cell + DVec3::splat(0.5)).floor();
            if !(first.is_finite() && last.is_finite())
                || first.abs().max_element() > 1e15
                || last.abs().max_element() > 1e15
            {
                continue;
            }
            let (first, last) = (first.as_i64vec3(), last.as_i64vec3());
            for z in first.z..=last.z {
                for y in first.y..=last.y {
                    for x in first.x..=last.x {
                        for items in level.cell(key([x, y, z])) {
                            out.extend(items.iter().filter(|item| item.reaches_box(lo, hi)));
                        }
                    }
                }
            }
        }
    }
}

/// The integer cell of `p` (relative to the grid's origin) in a grid of cells `cell` wide.
pub(crate) fn cell_of(p: DVec3, cell: f64) -> [i64; 3] {
    let f = (p / cell).floor();
    [f.x as i64, f.y as i64, f.z as i64]
}

/// Bits per axis of a [`key`].
pub(crate) const KEY_BITS: u32 = 21;

/// A cell's coordinates packed into one integer, [`KEY_BITS`] per axis. Coordinates beyond
/// that wrap: cells then share a key, which a support query tolerates (it sees a superset);
/// an exact use must keep its coordinates in `0..2^KEY_BITS`.
pub(crate) fn key(c: [i64; 3]) -> u64 {
    let m = (1u64 << KEY_BITS) - 1;
    ((c[0] as u64) & m)
        | (((c[1] as u64) & m) << KEY_BITS)
        | (((c[2] as u64) & m) << (2 * KEY_BITS))
}

/// Multiplicative hasher for already well-mixed 64-bit keys.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct MulHasher(u64);

impl Hasher for MulHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (v ^ (v >> 29)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every support containing `x`, by brute force, as ids.
    fn brute(centers: &[(DVec3, f64)], x: DVec3) -> Vec<usize> {
        let mut ids: Vec<usize> = (0..centers.len())
            .filter(|&i| (x - centers[i].0).length_squared() < centers[i].1 * centers[i].1)
            .collect();
        ids.sort_unstable();
        ids
    }

    #[test]
    fn inserted_supports_are_found_like_built_ones_and_in_the_same_order_by_both_queries() {
        // 200 supports on a jittered lattice, radius 0.3; then 50 inserted, some larger than any
        // level the grid was built with (radius 2.5: a new level).
        let mut all: Vec<(DVec3, f64)> = (0..200)
            .map(|i| {
                let f = i as f64;
                (
                    DVec3::new((f * 0.37) % 3.0, (f * 0.61) % 2.0, (f * 0.13) % 1.0),
                    0.3,
                )
            })
            .collect();
        let (c, r): (Vec<DVec3>, Vec<f64>) = all.iter().copied().unzip();
        let mut grid = SupportGrid::new(&c, &r, 0.6);
        for k in 0..50 {
            let f = k as f64;
            let s = (
                DVec3::new((f * 0.71) % 3.0, (f * 0.29) % 2.0, 0.5),
                if k % 10 == 0 { 2.5 } else { 0.2 },
            );
            grid.insert(s.0, s.1, all.len() as u32);
            all.push(s);
        }
        grid.insert(DVec3::ZERO, f64::NAN, 999); // ignored
        for q in 0..300 {
            let f = q as f64;
            let x = DVec3::new(
                (f * 0.53) % 3.2 - 0.1,
                (f * 0.47) % 2.2 - 0.1,
                (f * 0.19) % 1.2,
            );
            let mut found = Vec::new();
            grid.for_each_containing(x, |i, rel, d2| {
                assert!(
                    (rel - (x - all[i].0)).length() < 1e-12
                        && (d2 - rel.length_squared()).abs() < 1e-12
                );
                found.push(i);
            });
            let mut gathered = Vec::new();
            grid.gather_box(x, x, &mut gathered);
            let gathered: Vec<usize> = gathered
                .iter()
                .filter(|it| (x - it.center).length_squared() < it.radius2)
                .map(|it| it.id as usize)
                .collect();
            assert_eq!(
                found, gathered,
                "the two queries meet the supports in one order at {x}"
            );
            found.sort_unstable();
            assert_eq!(found, brute(&all, x), "at {x}");
        }
    }
}

//! Where a blend finds its supports: the field's own index, or a list gathered once for a box
//! (block-wise sampling and meshing), whose blends give the same bits inside the box.

use glam::DVec3;

use super::GlobalField;
use crate::spatial::{SupportGrid, SupportItem};

impl GlobalField {
    /// Collect into `out` every support that reaches into the box `[lo, hi]` (for
    /// [`GlobalField::value_near`] at points of that box).
    pub fn gather_supports(&self, lo: DVec3, hi: DVec3, out: &mut SupportList) {
        let d = &*self.inner;
        d.grid.gather_box(lo, hi, &mut out.items);
        out.witnesses.clear();
        if let Some(w) = &d.witnesses {
            w.grid.gather_box(lo, hi, &mut out.witnesses);
        }
    }
}

/// Supports gathered for a box ([`GlobalField::gather_supports`]); reuse one per thread.
#[derive(Debug, Clone, Default)]
pub struct SupportList {
    pub(super) items: Vec<SupportItem>,
    /// The trust witnesses reaching the box, where the field has them (a thinned field's).
    pub(super) witnesses: Vec<SupportItem>,
}

impl SupportList {
    /// An empty list.
    pub fn new() -> Self {
        Self::default()
    }

    /// Replace `out` by the supports of this list that reach into the smaller box `[lo, hi]`,
    /// in the same order (so blends over either list give the same bits inside that box).
    pub fn narrow_to(&self, lo: DVec3, hi: DVec3, out: &mut SupportList) {
        out.items.clear();
        out.items
            .extend(self.items.iter().filter(|item| item.reaches_box(lo, hi)));
        out.witnesses.clear();
        out.witnesses.extend(
            self.witnesses
                .iter()
                .filter(|item| item.reaches_box(lo, hi)),
        );
    }
}

/// Where a blend finds the supports containing a point.
pub(crate) trait Supports {
    /// Call `visit(i, x − cᵢ, |x − cᵢ|²)` for every support `i` containing `x` (`|x − cᵢ| < rᵢ`).
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64));
}

impl Supports for SupportGrid {
    #[inline]
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64)) {
        SupportGrid::for_each_containing(self, x, visit);
    }
}

impl Supports for SupportList {
    #[inline]
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64)) {
        Items(&self.items).for_each_containing(x, visit);
    }
}

/// Supports in a slice (a list's blend supports or its witnesses).
pub(super) struct Items<'a>(pub(super) &'a [SupportItem]);

impl Supports for Items<'_> {
    #[inline]
    fn for_each_containing(&self, x: DVec3, mut visit: impl FnMut(usize, DVec3, f64)) {
        for item in self.0 {
            let rel = x - item.center;
            let dist2 = rel.length_squared();
            if dist2 < item.radius2 {
                visit(item.id as usize, rel, dist2);
            }
        }
    }
}

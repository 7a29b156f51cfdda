//! The renderer's copy of the points, in immutable chunks shared between snapshots.
//!
//! A [`RenderSnapshot`](super::shared::RenderSnapshot) used to copy every point of the scene
//! each time the simulation published (10 Hz: 51 MB a second for a 1M-point scan, on the
//! simulation thread). Here the points are cut into chunks of at most [`CHUNK`] points, each
//! an `Arc`: a snapshot is a list of chunk pointers, and [`PointPublisher::publish`] copies
//! only the chunks holding a point marked changed since the last publish (or every chunk after
//! [`PointPublisher::mark_all`]). Chunks never span two objects, so points appended to one
//! object do not shift another's chunks. The renderer finds what changed by pointer identity
//! (an unchanged chunk is the same `Arc`) and compares only the chunks that are new.
//!
//! Contract: publishing costs O(chunks + points in changed chunks); a chunk once published is
//! never mutated.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;

/// Serial numbers of chunks (unlike addresses, never reused).
static NEXT_CHUNK_ID: AtomicU64 = AtomicU64::new(1);

/// Most points per chunk (4096 points ≈ 200 KB).
pub const CHUNK: usize = 4096;

/// Points of one chunk: positions, unit normals and colours, of equal length.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointChunk {
    /// Unique serial number: two chunks with the same id hold the same points.
    pub id: u64,
    /// Positions (m).
    pub positions: Vec<DVec3>,
    /// Unit normals.
    pub normals: Vec<DVec3>,
    /// sRGB colours.
    pub colors: Vec<[u8; 3]>,
}

impl PointChunk {
    /// Copy `range` of one object's arrays.
    fn copy(p: &[DVec3], n: &[DVec3], c: &[[u8; 3]], range: std::ops::Range<usize>) -> Self {
        Self {
            id: NEXT_CHUNK_ID.fetch_add(1, Ordering::Relaxed),
            positions: p[range.clone()].to_vec(),
            normals: n[range.clone()].to_vec(),
            colors: c[range].to_vec(),
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// The points of a snapshot: chunks in order, their concatenation is the point list.
#[derive(Debug, Clone, Default)]
pub struct ChunkedPoints {
    chunks: Vec<Arc<PointChunk>>,
    len: usize,
}

impl ChunkedPoints {
    /// One object's points, chunked (a test or one-off snapshot; no sharing with anything).
    pub fn from_slices(positions: &[DVec3], normals: &[DVec3], colors: &[[u8; 3]]) -> Self {
        let mut p = PointPublisher::default();
        p.publish(&[ObjectPoints {
            positions,
            normals,
            colors,
        }])
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The chunks, in order.
    pub fn chunks(&self) -> &[Arc<PointChunk>] {
        &self.chunks
    }

    /// All positions, in order.
    pub fn positions(&self) -> impl Iterator<Item = &DVec3> + '_ {
        self.chunks.iter().flat_map(|c| c.positions.iter())
    }

    /// All normals, in order.
    pub fn normals(&self) -> impl Iterator<Item = &DVec3> + '_ {
        self.chunks.iter().flat_map(|c| c.normals.iter())
    }

    /// All colours, in order.
    pub fn colors(&self) -> impl Iterator<Item = &[u8; 3]> + '_ {
        self.chunks.iter().flat_map(|c| c.colors.iter())
    }

    /// Changes when any point changes: the chunks' ids, O(chunks).
    pub fn key(&self) -> (usize, u64) {
        let h = self.chunks.iter().fold(0u64, |h, c| {
            (h ^ c.id).wrapping_mul(0x0100_0000_01b3).rotate_left(7)
        });
        (self.len, h)
    }
}

/// One object's arrays, as the publisher reads them.
#[derive(Debug, Clone, Copy)]
pub struct ObjectPoints<'a> {
    /// Positions.
    pub positions: &'a [DVec3],
    /// Normals (same length).
    pub normals: &'a [DVec3],
    /// Colours (same length).
    pub colors: &'a [[u8; 3]],
}

/// Keeps the last published chunks and the marks of what changed since; lives with the
/// simulation. Objects are addressed by their position in the list given to
/// [`PointPublisher::publish`].
#[derive(Debug, Default)]
pub struct PointPublisher {
    /// Per object: its chunks as last published.
    objects: Vec<Vec<Arc<PointChunk>>>,
    /// Per object: chunks marked changed.
    dirty: Vec<Vec<bool>>,
    all: bool,
}

impl PointPublisher {
    /// A publisher that copies everything at its first publish.
    pub fn new() -> Self {
        Self {
            all: true,
            ..Self::default()
        }
    }

    /// Everything changed (objects added, removed, replaced or reordered).
    pub fn mark_all(&mut self) {
        self.all = true;
    }

    /// Point `i` of object `object` changed (moved, recoloured, or appended).
    pub fn mark(&mut self, object: usize, i: usize) {
        if self.dirty.len() <= object {
            self.dirty.resize(object + 1, Vec::new());
        }
        let d = &mut self.dirty[object];
        let c = i / CHUNK;
        if d.len() <= c {
            d.resize(c + 1, false);
        }
        d[c] = true;
    }

    /// [`PointPublisher::mark`] for many points.
    pub fn mark_many(&mut self, object: usize, indices: impl IntoIterator<Item = usize>) {
        for i in indices {
            self.mark(object, i);
        }
    }

    /// The snapshot of `objects`: chunks with no marked point and an unchanged length are
    /// shared with the previous snapshot; the marks are cleared.
    pub fn publish(&mut self, objects: &[ObjectPoints<'_>]) -> ChunkedPoints {
        if self.all || self.objects.len() != objects.len() {
            self.objects.clear();
            self.objects.resize(objects.len(), Vec::new());
            self.all = false;
            self.dirty.clear();
        }
        let mut out = ChunkedPoints::default();
        for (o, src) in objects.iter().enumerate() {
            let n = src.positions.len();
            debug_assert!(src.normals.len() == n && src.colors.len() == n);
            let old = &mut self.objects[o];
            let dirty = self.dirty.get(o).map_or(&[][..], |d| &d[..]);
            let chunks = n.div_ceil(CHUNK);
            old.truncate(chunks);
            for c in 0..chunks {
                let range = c * CHUNK..((c + 1) * CHUNK).min(n);
                let stale = old
                    .get(c)
                    .is_none_or(|x| x.len() != range.len() || dirty.get(c) == Some(&true));
                if stale {
                    let chunk = Arc::new(PointChunk::copy(
                        src.positions,
                        src.normals,
                        src.colors,
                        range,
                    ));
                    if c < old.len() {
                        old[c] = chunk;
                    } else {
                        old.push(chunk);
                    }
                }
            }
            out.chunks.extend(old.iter().cloned());
            out.len += n;
        }
        for d in &mut self.dirty {
            d.clear();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(n: usize, shift: f64) -> (Vec<DVec3>, Vec<DVec3>, Vec<[u8; 3]>) {
        let p = (0..n)
            .map(|i| DVec3::new(i as f64 + shift, 0.0, 0.0))
            .collect();
        (p, vec![DVec3::Z; n], vec![[1, 2, 3]; n])
    }

    fn view(o: &(Vec<DVec3>, Vec<DVec3>, Vec<[u8; 3]>)) -> ObjectPoints<'_> {
        ObjectPoints {
            positions: &o.0,
            normals: &o.1,
            colors: &o.2,
        }
    }

    #[test]
    fn only_marked_chunks_are_copied_and_objects_do_not_share_chunks() {
        let mut a = object(3 * CHUNK + 5, 0.0);
        let b = object(10, 1e6);
        let mut p = PointPublisher::new();
        let s1 = p.publish(&[view(&a), view(&b)]);
        assert_eq!(s1.len(), a.0.len() + 10);
        assert_eq!(s1.chunks().len(), 5);
        a.0[CHUNK + 7].y = 1.0;
        p.mark(0, CHUNK + 7);
        // Appended points: the last chunk of `a` grows, `b`'s chunk stays shared.
        a.0.push(DVec3::ONE);
        a.1.push(DVec3::Z);
        a.2.push([0; 3]);
        p.mark(0, a.0.len() - 1);
        let s2 = p.publish(&[view(&a), view(&b)]);
        let same: Vec<bool> = s1
            .chunks()
            .iter()
            .zip(s2.chunks())
            .map(|(x, y)| Arc::ptr_eq(x, y))
            .collect();
        assert_eq!(same, [true, false, true, false, true]);
        let flat: Vec<DVec3> = s2.positions().copied().collect();
        assert_eq!(flat[..a.0.len()], a.0[..]);
        assert_eq!(flat[a.0.len()..], b.0[..]);
        // Unmarked changes are not seen (the marks are the contract); mark_all copies all.
        p.mark_all();
        let s3 = p.publish(&[view(&a), view(&b)]);
        assert!(
            s3.chunks()
                .iter()
                .zip(s2.chunks())
                .all(|(x, y)| !Arc::ptr_eq(x, y))
        );
    }
}

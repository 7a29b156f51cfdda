//! The shared scene's edit format (docs/SHARING.md has the same table for other languages): a
//! sculpted object's whole point set after a commit, little-endian, no I/O.
//!
//! ```text
//! offset  size        field
//! 0       4           magic "HSS1"
//! 4       1           kind: 1 proposal (a station's commit), 2 ordered (the keeper's)
//! 5       3           zero
//! 8       8           seq: u64, the scene's version once ordered (1, 2, …); in a proposal,
//!                     the version it was made from (0: none)
//! 16      8           t: u64, the author's clock at the commit (ns since the UNIX epoch)
//! 24      2+len       scene name (u16 length, UTF-8)
//! …       2+len       object name (the sculpted one)
//! …       2           m: u16, objects shown
//! …       m·(2+len)   their names (the others were consumed by operations)
//! …       2+len       author station
//! …       8           author's counter (u64): (author, counter) names this state
//! …       2+len       parent's author (empty: a scene's first state)
//! …       8           parent's counter: the state this one was made from
//! …       4           n: u32 points
//! …       24·n        positions, f64 x, y, z (m)
//! …       12·n        unit normals, f32 x, y, z
//! …       3·n         colours, sRGB u8 r, g, b
//! ```
//!
//! Every field is checked on decoding ([`decode`]): a bad state is refused with what is wrong,
//! never half applied.

use glam::DVec3;

/// First bytes of every state.
pub const MAGIC: &[u8; 4] = b"HSS1";
/// Most points a shared state may carry.
pub const MAX_SHARED_POINTS: usize = 5_000_000;
/// Longest name (scene, object, station), bytes.
pub const MAX_NAME_BYTES: usize = 200;
/// Most objects a state may name as shown.
pub const MAX_VISIBLE: usize = 1024;

/// Whether a state is a station's proposal or the keeper's ordered version of one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A station's commit, not yet ordered.
    Proposal = 1,
    /// Ordered by the keeper: the scene's version `seq`.
    Ordered = 2,
}

/// Names a state: the station that made it and its count of states made.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub struct StateId {
    /// The author station.
    pub station: String,
    /// The author's counter.
    pub counter: u64,
}

impl std::fmt::Display for StateId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}#{}", self.station, self.counter)
    }
}

/// An object's points as a shared state.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedState {
    /// Proposal or ordered.
    pub kind: Kind,
    /// The scene's version once ordered; in a proposal, the version it was made from.
    pub seq: u64,
    /// The author's clock at the commit, ns since the UNIX epoch (edit propagation is measured
    /// against it on one machine or with synchronised clocks).
    pub t_unix_ns: u64,
    /// The scene.
    pub scene: String,
    /// The sculpted object.
    pub object: String,
    /// The objects shown.
    pub visible: Vec<String>,
    /// This state.
    pub id: StateId,
    /// The state it was made from (`None`: the scene's first).
    pub parent: Option<StateId>,
    /// Positions (m).
    pub positions: Vec<DVec3>,
    /// Unit normals.
    pub normals: Vec<[f32; 3]>,
    /// sRGB colours.
    pub colors: Vec<[u8; 3]>,
}

/// Why bytes are not a shared state.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// Shorter than its fields say.
    #[error("truncated: {0}")]
    Truncated(&'static str),
    /// Not this format.
    #[error("not a shared state (magic {0:02x?})")]
    Magic([u8; 4]),
    /// Unknown kind byte.
    #[error("unknown kind {0}")]
    Kind(u8),
    /// A name is not UTF-8, too long, or not usable in a key expression.
    #[error("bad {0} name")]
    Name(&'static str),
    /// More points than [`MAX_SHARED_POINTS`].
    #[error("{0} points (at most {MAX_SHARED_POINTS})")]
    TooMany(usize),
    /// More shown objects than [`MAX_VISIBLE`].
    #[error("{0} shown objects (at most {MAX_VISIBLE})")]
    TooManyObjects(usize),
    /// A position or normal that is not finite, or a normal that is not unit length.
    #[error("point {index}: {what}")]
    Point {
        /// The point.
        index: usize,
        /// What is wrong with it.
        what: &'static str,
    },
    /// Bytes after the last field.
    #[error("{0} bytes after the last field")]
    Trailing(usize),
}

impl WireError {
    /// A short name for counting rejections by kind.
    pub fn name(&self) -> &'static str {
        match self {
            WireError::Truncated(_) => "truncated",
            WireError::Magic(_) => "bad magic",
            WireError::Kind(_) => "unknown kind",
            WireError::Name(_) => "bad name",
            WireError::TooMany(_) => "too many points",
            WireError::TooManyObjects(_) => "too many objects",
            WireError::Point { .. } => "bad point",
            WireError::Trailing(_) => "trailing bytes",
        }
    }
}

/// Whether `name` can be one chunk of a key expression (and a file name): 1–200 bytes of
/// letters, digits, `-`, `_` and `.`.
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME_BYTES
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
}

/// The state's bytes.
pub fn encode(s: &SharedState) -> Vec<u8> {
    let n = s.positions.len();
    let mut out = Vec::with_capacity(64 + 39 * n);
    out.extend_from_slice(MAGIC);
    out.push(s.kind as u8);
    out.extend_from_slice(&[0; 3]);
    out.extend_from_slice(&s.seq.to_le_bytes());
    out.extend_from_slice(&s.t_unix_ns.to_le_bytes());
    let name = |out: &mut Vec<u8>, v: &str| {
        out.extend_from_slice(&(v.len() as u16).to_le_bytes());
        out.extend_from_slice(v.as_bytes());
    };
    name(&mut out, &s.scene);
    name(&mut out, &s.object);
    out.extend_from_slice(&(s.visible.len() as u16).to_le_bytes());
    for v in &s.visible {
        name(&mut out, v);
    }
    name(&mut out, &s.id.station);
    out.extend_from_slice(&s.id.counter.to_le_bytes());
    let (ps, pc) = s
        .parent
        .as_ref()
        .map_or(("", 0), |p| (p.station.as_str(), p.counter));
    out.extend_from_slice(&(ps.len() as u16).to_le_bytes());
    out.extend_from_slice(ps.as_bytes());
    out.extend_from_slice(&pc.to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    for p in &s.positions {
        for v in p.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for nrm in &s.normals {
        for v in nrm {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for c in &s.colors {
        out.extend_from_slice(c);
    }
    out
}

/// Turn a proposal's bytes into the ordered state `seq` in place (kind and seq are fixed-size
/// fields at the front: the points are not copied).
pub fn order_in_place(bytes: &mut [u8], seq: u64) {
    bytes[4] = Kind::Ordered as u8;
    bytes[8..16].copy_from_slice(&seq.to_le_bytes());
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], WireError> {
        let end = self.at.checked_add(n).ok_or(WireError::Truncated(what))?;
        let s = self.b.get(self.at..end).ok_or(WireError::Truncated(what))?;
        self.at = end;
        Ok(s)
    }
    fn u16(&mut self, what: &'static str) -> Result<u16, WireError> {
        Ok(u16::from_le_bytes(
            self.take(2, what)?.try_into().expect("2"),
        ))
    }
    fn u32(&mut self, what: &'static str) -> Result<u32, WireError> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4"),
        ))
    }
    fn u64(&mut self, what: &'static str) -> Result<u64, WireError> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8"),
        ))
    }
    fn name(&mut self, what: &'static str, may_be_empty: bool) -> Result<String, WireError> {
        let n = self.u16(what)? as usize;
        let s = std::str::from_utf8(self.take(n, what)?).map_err(|_| WireError::Name(what))?;
        if (s.is_empty() && may_be_empty) || valid_name(s) {
            Ok(s.to_owned())
        } else {
            Err(WireError::Name(what))
        }
    }
}

/// Decode and check a state (see the module doc for the layout and [`WireError`] for what is
/// refused).
pub fn decode(bytes: &[u8]) -> Result<SharedState, WireError> {
    let mut r = Reader { b: bytes, at: 0 };
    let magic: [u8; 4] = r.take(4, "magic")?.try_into().expect("4");
    if &magic != MAGIC {
        return Err(WireError::Magic(magic));
    }
    let kind = match r.take(4, "kind")?[0] {
        1 => Kind::Proposal,
        2 => Kind::Ordered,
        k => return Err(WireError::Kind(k)),
    };
    let seq = r.u64("seq")?;
    let t_unix_ns = r.u64("time")?;
    let scene = r.name("scene", false)?;
    let object = r.name("object", false)?;
    let m = r.u16("shown objects")? as usize;
    if m > MAX_VISIBLE {
        return Err(WireError::TooManyObjects(m));
    }
    let visible = (0..m)
        .map(|_| r.name("shown object", false))
        .collect::<Result<Vec<_>, _>>()?;
    let station = r.name("author", false)?;
    let counter = r.u64("author's counter")?;
    let parent_station = r.name("parent's author", true)?;
    let parent_counter = r.u64("parent's counter")?;
    let n = r.u32("point count")? as usize;
    if n > MAX_SHARED_POINTS {
        return Err(WireError::TooMany(n));
    }
    let pos = r.take(24 * n, "positions")?;
    let nrm = r.take(12 * n, "normals")?;
    let col = r.take(3 * n, "colours")?;
    if r.at != bytes.len() {
        return Err(WireError::Trailing(bytes.len() - r.at));
    }
    let f64s = |c: &[u8]| f64::from_le_bytes(c.try_into().expect("8"));
    let f32s = |c: &[u8]| f32::from_le_bytes(c.try_into().expect("4"));
    let mut positions = Vec::with_capacity(n);
    for (index, c) in pos.chunks_exact(24).enumerate() {
        let p = DVec3::new(f64s(&c[0..8]), f64s(&c[8..16]), f64s(&c[16..24]));
        if !p.is_finite() {
            return Err(WireError::Point {
                index,
                what: "position not finite",
            });
        }
        positions.push(p);
    }
    let mut normals = Vec::with_capacity(n);
    for (index, c) in nrm.chunks_exact(12).enumerate() {
        let v = [f32s(&c[0..4]), f32s(&c[4..8]), f32s(&c[8..12])];
        let len2: f32 = v.iter().map(|x| x * x).sum();
        if !len2.is_finite() || (len2 - 1.0).abs() > 1e-3 {
            return Err(WireError::Point {
                index,
                what: "normal not unit length",
            });
        }
        normals.push(v);
    }
    let colors = col.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(SharedState {
        kind,
        seq,
        t_unix_ns,
        scene,
        object,
        visible,
        id: StateId { station, counter },
        parent: (!parent_station.is_empty()).then_some(StateId {
            station: parent_station,
            counter: parent_counter,
        }),
        positions,
        normals,
        colors,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn state(n: usize) -> SharedState {
        SharedState {
            kind: Kind::Proposal,
            seq: 0,
            t_unix_ns: 1_700_000_000_000_000_000,
            scene: "demo".into(),
            object: "ball".into(),
            visible: vec!["ball".into(), "knob".into()],
            id: StateId {
                station: "a".into(),
                counter: 3,
            },
            parent: Some(StateId {
                station: "b".into(),
                counter: 7,
            }),
            positions: (0..n)
                .map(|i| DVec3::new(i as f64 * 1e-3, 0.1, -0.2))
                .collect(),
            normals: vec![[0.0, 0.0, 1.0]; n],
            colors: vec![[200, 40, 30]; n],
        }
    }

    #[test]
    fn states_round_trip_bit_for_bit_and_order_in_place() {
        let s = state(5);
        let mut b = encode(&s);
        assert_eq!(b.len(), 24 + 6 + 6 + 2 + 6 + 6 + 3 + 8 + 3 + 8 + 4 + 39 * 5);
        assert_eq!(decode(&b).unwrap(), s);
        order_in_place(&mut b, 42);
        let o = decode(&b).unwrap();
        assert_eq!((o.kind, o.seq), (Kind::Ordered, 42));
        assert_eq!(o.positions, s.positions);
        let first = SharedState {
            parent: None,
            ..state(0)
        };
        assert_eq!(decode(&encode(&first)).unwrap(), first);
    }

    #[test]
    fn every_bad_field_is_refused_by_name() {
        let good = encode(&state(3));
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(decode(&bad).unwrap_err().name(), "bad magic");
        for cut in [3, 10, 40, good.len() - 1] {
            assert_eq!(decode(&good[..cut]).unwrap_err().name(), "truncated");
        }
        let mut longer = good.clone();
        longer.push(0);
        assert_eq!(decode(&longer).unwrap_err(), WireError::Trailing(1));
        let mut s = state(3);
        s.positions[1].y = f64::NAN;
        assert_eq!(
            decode(&encode(&s)).unwrap_err(),
            WireError::Point {
                index: 1,
                what: "position not finite"
            }
        );
        let mut s = state(3);
        s.normals[2] = [0.0, 0.0, 2.0];
        assert_eq!(decode(&encode(&s)).unwrap_err().name(), "bad point");
        let mut s = state(1);
        s.scene = "a/b".into();
        assert_eq!(decode(&encode(&s)).unwrap_err(), WireError::Name("scene"));
        let mut huge = good.clone();
        let at = good.len() - 39 * 3 - 4;
        huge[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(decode(&huge).unwrap_err().name(), "too many points");
        let mut k = good;
        k[4] = 9;
        assert_eq!(decode(&k).unwrap_err(), WireError::Kind(9));
    }
}

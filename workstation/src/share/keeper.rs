//! The scene keeper: one truth per scene, in order. Deterministic, no I/O, no clock; the router
//! ([`super::router`]) drives it.
//!
//! Each station proposes its commits (a sculpted object's whole point set, [`super::wire`])
//! naming the state it made them from. The keeper accepts a proposal whose parent is the
//! scene's current state (or, for a scene with no state yet, a first state without a parent),
//! numbers it (the scene's next version) and hands it back to be published to every station;
//! it refuses any other, saying why. Every accepted state is made from the one before it, so
//! the versions are one history and every station that applies them in order holds the same
//! points. A station whose proposal was refused (another station's commit got in first) takes
//! the newer state instead: its stroke is undone, nothing anyone committed is lost. A proposal
//! sent again (its answer was lost with a link) gets the same answer; a keeper with no state
//! (a router restarted without `--store`) takes the first proposal it gets as the scene's
//! state, numbered after the version it was made from, so the stations carry the scene over.

use std::collections::BTreeMap;

use super::wire::{self, Kind, SharedState, StateId};

/// The keeper's answer to a proposal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Accepted as version `seq`: publish `ordered` (the state's bytes, ordered) to everyone.
    Accepted {
        /// The state.
        id: StateId,
        /// Its version.
        seq: u64,
        /// Its bytes as an ordered state.
        ordered: Vec<u8>,
    },
    /// Refused: `reason` (a short name, counted) and what is wrong in words.
    Refused {
        /// The state, when its bytes said.
        id: Option<StateId>,
        /// The kind of refusal ([`Keeper::refusals`] counts them by it).
        reason: &'static str,
        /// In words.
        message: String,
    },
}

/// One scene's keeper.
#[derive(Debug, Default)]
pub struct Keeper {
    scene: String,
    /// The current state's id and version, and its ordered bytes.
    current: Option<(StateId, u64, Vec<u8>)>,
    /// The current state's points.
    points: usize,
    refusals: BTreeMap<&'static str, u64>,
}

impl Keeper {
    /// The keeper of scene `scene`, with no state yet.
    pub fn new(scene: &str) -> Self {
        Self {
            scene: scene.to_owned(),
            ..Self::default()
        }
    }

    /// The scene's current version (0: no state yet).
    pub fn version(&self) -> u64 {
        self.current.as_ref().map_or(0, |c| c.1)
    }

    /// A keeper holding `ordered` (a stored state of scene `scene`), as after accepting it.
    pub fn restore(scene: &str, ordered: Vec<u8>) -> Result<Self, String> {
        let s = wire::decode(&ordered).map_err(|e| e.to_string())?;
        if s.kind != Kind::Ordered || s.scene != scene || s.seq == 0 {
            return Err(format!(
                "a {:?} state of scene `{}` version {}, not scene `{scene}`'s ordered state",
                s.kind, s.scene, s.seq
            ));
        }
        Ok(Self {
            scene: scene.to_owned(),
            points: s.positions.len(),
            current: Some((s.id, s.seq, ordered)),
            refusals: BTreeMap::new(),
        })
    }

    /// The current state's point count.
    pub fn points(&self) -> usize {
        self.points
    }

    /// The current state's id.
    pub fn current(&self) -> Option<&StateId> {
        self.current.as_ref().map(|c| &c.0)
    }

    /// The current state's bytes (ordered), for a station that joins or catches up.
    pub fn snapshot(&self) -> Option<&[u8]> {
        self.current.as_ref().map(|c| c.2.as_slice())
    }

    /// Refusals so far, by kind.
    pub fn refusals(&self) -> &BTreeMap<&'static str, u64> {
        &self.refusals
    }

    /// Judge `bytes`, proposed by station `from` (the station named in the key it came on).
    pub fn propose(&mut self, from: &str, bytes: &[u8]) -> Verdict {
        match self.judge(from, bytes) {
            Ok((state, seq)) => {
                let mut ordered = bytes.to_vec();
                wire::order_in_place(&mut ordered, seq);
                self.points = state.positions.len();
                self.current = Some((state.id.clone(), seq, ordered.clone()));
                Verdict::Accepted {
                    id: state.id,
                    seq,
                    ordered,
                }
            }
            Err((id, reason, message)) => {
                *self.refusals.entry(reason).or_default() += 1;
                Verdict::Refused {
                    id,
                    reason,
                    message,
                }
            }
        }
    }

    #[allow(clippy::type_complexity)]
    fn judge(
        &self,
        from: &str,
        bytes: &[u8],
    ) -> Result<(SharedState, u64), (Option<StateId>, &'static str, String)> {
        let s = wire::decode(bytes).map_err(|e| (None, e.name(), e.to_string()))?;
        let id = Some(s.id.clone());
        let refuse = |reason, message: String| Err((id.clone(), reason, message));
        if s.kind != Kind::Proposal {
            return refuse("not a proposal", "only proposals are ordered".into());
        }
        if s.scene != self.scene {
            return refuse(
                "wrong scene",
                format!("a state of scene `{}` sent to `{}`", s.scene, self.scene),
            );
        }
        if s.id.station != from {
            return refuse(
                "author mismatch",
                format!("made by `{}` but sent by `{from}`", s.id.station),
            );
        }
        match (&self.current, &s.parent) {
            // A proposal sent again (its answer was lost): the same answer.
            (Some((cur, seq, _)), _) if *cur == s.id => Ok((s, *seq)),
            (None, None) => Ok((s, 1)),
            // A router restarted without its store: the first station to propose after it
            // re-seeds the scene, numbered after its parent's version (a proposal's `seq`).
            (None, Some(_)) => {
                let seq = s.seq.saturating_add(1);
                Ok((s, seq))
            }
            (Some((cur, _, _)), None) => refuse(
                "stale",
                format!("a first state, but the scene is at {cur} already"),
            ),
            (Some((cur, seq, _)), Some(p)) if p == cur => Ok((s, seq + 1)),
            (Some((cur, seq, _)), Some(p)) => refuse(
                "stale",
                format!("made from {p}, but the scene is at {cur} (version {seq})"),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn proposal(station: &str, counter: u64, parent: Option<(&str, u64)>, x: f64) -> Vec<u8> {
        wire::encode(&SharedState {
            kind: Kind::Proposal,
            seq: 0,
            t_unix_ns: 0,
            scene: "demo".into(),
            object: "ball".into(),
            visible: vec!["ball".into()],
            id: StateId {
                station: station.into(),
                counter,
            },
            parent: parent.map(|(s, c)| StateId {
                station: s.into(),
                counter: c,
            }),
            positions: vec![DVec3::new(x, 0.0, 0.0)],
            normals: vec![[0.0, 0.0, 1.0]],
            colors: vec![[1, 2, 3]],
        })
    }

    fn seq(v: Verdict) -> u64 {
        match v {
            Verdict::Accepted { seq, .. } => seq,
            Verdict::Refused { message, .. } => panic!("refused: {message}"),
        }
    }

    fn reason(v: Verdict) -> &'static str {
        match v {
            Verdict::Refused { reason, .. } => reason,
            Verdict::Accepted { seq, .. } => panic!("accepted as {seq}"),
        }
    }

    #[test]
    fn one_history_in_order_and_a_stale_commit_refused() {
        let mut k = Keeper::new("demo");
        assert_eq!(k.snapshot(), None);
        assert_eq!(seq(k.propose("a", &proposal("a", 1, None, 0.0))), 1);
        // A second first state (b joined at the same time): refused, b takes a's.
        assert_eq!(
            reason(k.propose("b", &proposal("b", 1, None, 0.5))),
            "stale"
        );
        // a's next commit, made from its first; then b's, made from a's second.
        assert_eq!(
            seq(k.propose("a", &proposal("a", 2, Some(("a", 1)), 1.0))),
            2
        );
        assert_eq!(
            seq(k.propose("b", &proposal("b", 2, Some(("a", 2)), 2.0))),
            3
        );
        // a commits again from its own second state: b's got in first.
        assert_eq!(
            reason(k.propose("a", &proposal("a", 3, Some(("a", 2)), 3.0))),
            "stale"
        );
        // b's proposal again (its verdict was lost): the same answer, no new version.
        assert_eq!(
            seq(k.propose("b", &proposal("b", 2, Some(("a", 2)), 2.0))),
            3
        );
        // The snapshot is b's state, ordered as version 3.
        let s = wire::decode(k.snapshot().unwrap()).unwrap();
        assert_eq!((s.kind, s.seq, s.positions[0].x), (Kind::Ordered, 3, 2.0));
        assert_eq!(k.version(), 3);
        assert_eq!(k.refusals().get("stale"), Some(&2));
        // A restarted router reads it back and goes on from it.
        let mut r = Keeper::restore("demo", k.snapshot().unwrap().to_vec()).unwrap();
        assert_eq!((r.version(), r.points()), (3, 1));
        assert_eq!(
            seq(r.propose("a", &proposal("a", 4, Some(("b", 2)), 4.0))),
            4
        );
        assert!(Keeper::restore("other", k.snapshot().unwrap().to_vec()).is_err());
        // Restarted without a store: a station re-seeds the scene after the version it holds.
        let mut empty = Keeper::new("demo");
        let mut reseed = proposal("a", 9, Some(("b", 2)), 5.0);
        reseed[8..16].copy_from_slice(&3u64.to_le_bytes());
        assert_eq!(seq(empty.propose("a", &reseed)), 4);
        assert!(Keeper::restore("demo", proposal("a", 1, None, 0.0)).is_err());
    }

    #[test]
    fn malformed_and_misaddressed_states_are_refused_and_counted_by_name() {
        let mut k = Keeper::new("demo");
        assert_eq!(reason(k.propose("a", b"HSS")), "truncated");
        let mut bad = proposal("a", 1, None, 0.0);
        bad[0] = b'Z';
        assert_eq!(reason(k.propose("a", &bad)), "bad magic");
        assert_eq!(
            reason(k.propose("b", &proposal("a", 1, None, 0.0))),
            "author mismatch"
        );
        let mut ordered = proposal("a", 1, None, 0.0);
        wire::order_in_place(&mut ordered, 9);
        assert_eq!(reason(k.propose("a", &ordered)), "not a proposal");
        let mut nan = proposal("a", 1, None, f64::NAN);
        assert_eq!(reason(k.propose("a", &nan)), "bad point");
        nan.clear();
        assert_eq!(k.version(), 0, "nothing refused was applied");
        assert_eq!(k.refusals().values().sum::<u64>(), 5);
        let mut other = Keeper::new("other");
        assert_eq!(
            reason(other.propose("a", &proposal("a", 1, None, 0.0))),
            "wrong scene"
        );
    }
}

//! Shared scenes (issue 22, DESIGN §6c): several stations sculpt one surface over Zenoh, each
//! with its own haptics server and force loop; viewers and recorders join at any time.
//!
//! **One truth, in order.** Each station simulates and feels its own replica; what crosses the
//! bus is committed shape, never 1 kHz force. When a station commits (a stroke's release, an
//! operation), it proposes the sculpted object's whole point set, naming the state it made it
//! from; the [`keeper`] (in `workstation share-router`) orders the proposals made from the
//! scene's current state and refuses the others; every station adopts each ordered state it did
//! not make ([`book`]). So the versions are one history, every station ends with the same
//! points bit for bit, a late joiner or a restarted station takes the current state and is
//! identical, and a stroke made from a state someone else replaced meanwhile is undone (said),
//! never merged into a shape nobody made. Why not replicated simulations with ordered inputs:
//! the dynamics are driven at 1 kHz by each hand, so every station would have to wait for
//! every other's inputs each step (lockstep) or roll back; why not one authoritative simulation
//! that every station's tools drive: a station's touch would then lag by the round trip to it.
//! The price of this model is that two stations cannot sculpt the same object at the same
//! moment: they take turns, and the second of two overlapping strokes is undone.
//!
//! Keys (docs/SHARING.md has the layouts):
//! - `haptic-sculpt/<scene>/propose/<station>`: a station's commit ([`wire`], kind 1);
//! - `haptic-sculpt/<scene>/edits`: the keeper's ordered states (kind 2), in order;
//! - `haptic-sculpt/<scene>/state`: a queryable answering the current state (kind 2);
//! - `haptic-sculpt/<scene>/verdicts/<station>`: the keeper's answer to a station (JSON);
//! - `haptic-sculpt/<scene>/keeper`: the keeper's status twice a second (JSON);
//! - `haptic-sculpt/<scene>/telemetry/<station>`: each station's cursor, force, button, tool,
//!   rates and round trip, JSON at 125 Hz ([`Telemetry`]).

pub mod book;
pub mod bus;
pub mod identity;
pub mod keeper;
pub mod router;
pub mod station;
pub mod wire;

/// The first chunk of every key.
pub const ROOT: &str = "haptic-sculpt";

/// The keys of scene `scene`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Keys {
    scene: String,
}

impl Keys {
    /// Keys of `scene` (a valid name, [`wire::valid_name`]).
    pub fn new(scene: &str) -> Self {
        Self {
            scene: scene.to_owned(),
        }
    }

    /// The scene's name.
    pub fn scene(&self) -> &str {
        &self.scene
    }

    /// Where station `station` proposes its commits.
    pub fn propose(&self, station: &str) -> String {
        format!("{ROOT}/{}/propose/{station}", self.scene)
    }

    /// Every station's proposals (the keeper's subscription).
    pub fn proposals(&self) -> String {
        format!("{ROOT}/{}/propose/*", self.scene)
    }

    /// The ordered states.
    pub fn edits(&self) -> String {
        format!("{ROOT}/{}/edits", self.scene)
    }

    /// The current state's queryable.
    pub fn state(&self) -> String {
        format!("{ROOT}/{}/state", self.scene)
    }

    /// The keeper's answers to station `station`.
    pub fn verdicts(&self, station: &str) -> String {
        format!("{ROOT}/{}/verdicts/{station}", self.scene)
    }

    /// The keeper's status.
    pub fn keeper(&self) -> String {
        format!("{ROOT}/{}/keeper", self.scene)
    }

    /// Station `station`'s telemetry.
    pub fn telemetry(&self, station: &str) -> String {
        format!("{ROOT}/{}/telemetry/{station}", self.scene)
    }

    /// Every station's telemetry.
    pub fn all_telemetry(&self) -> String {
        format!("{ROOT}/{}/telemetry/*", self.scene)
    }
}

/// The station's name in a key (`*` and `/` would change what the key matches): the last
/// chunk of `key`, if it is a valid name.
pub fn station_of(key: &str) -> Option<&str> {
    key.rsplit('/').next().filter(|s| wire::valid_name(s))
}

/// One station's telemetry sample (JSON on `haptic-sculpt/<scene>/telemetry/<station>`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Telemetry {
    /// The station.
    pub station: String,
    /// The station's clock, ns since its session started (monotonic).
    pub t_ns: u64,
    /// The cursor in the scene (m); absent before the first.
    pub cursor: Option<[f64; 3]>,
    /// The force the station's device is sent (N, scene frame).
    pub force: [f64; 3],
    /// Buttons (bit 0: the stylus button).
    pub buttons: u16,
    /// The tool selected or engaged.
    pub tool: Option<String>,
    /// The force-mapping loop's rate (Hz).
    pub force_loop_hz: f64,
    /// The simulation's rate (Hz).
    pub sim_hz: f64,
    /// Cursor → force round trip at the station's haptics server, p50 (µs; 0 without one).
    pub rtt_us: f64,
    /// The scene version the station holds.
    pub version: u64,
}

/// The keeper's answer to a station's proposal (JSON on `…/verdicts/<station>`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct VerdictMessage {
    /// The state (`station#counter`), when its bytes said.
    pub id: Option<String>,
    /// Its author.
    pub station: Option<String>,
    /// Its author's counter.
    pub counter: Option<u64>,
    /// Whether it is now the scene's state.
    pub accepted: bool,
    /// Its version, when accepted.
    pub seq: Option<u64>,
    /// Why not (a short name: `stale`, `truncated`, `bad point`, …), when refused.
    pub reason: Option<String>,
    /// In words.
    pub message: Option<String>,
}

/// The keeper's status (JSON on `…/keeper`, twice a second).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KeeperStatus {
    /// The scene.
    pub scene: String,
    /// Its version (0: no state yet).
    pub version: u64,
    /// The current state (`station#counter`).
    pub current: Option<String>,
    /// Its points.
    pub points: u64,
    /// Proposals refused so far, by reason.
    pub refusals: std::collections::BTreeMap<String, u64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_and_station_names() {
        let k = Keys::new("demo");
        assert_eq!(k.propose("a"), "haptic-sculpt/demo/propose/a");
        assert_eq!(k.all_telemetry(), "haptic-sculpt/demo/telemetry/*");
        assert_eq!(
            station_of("haptic-sculpt/demo/propose/west-1"),
            Some("west-1")
        );
        assert_eq!(station_of("haptic-sculpt/demo/propose/**"), None);
    }
}

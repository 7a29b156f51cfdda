//! A station's books on the shared scene: which state it holds, which of its own commits are
//! waiting for the keeper, and what to do with each ordered state that comes. Deterministic,
//! no I/O.
//!
//! Every ordered state is the sculpted object's whole point set, so a station never needs the
//! states between the one it holds and a newer one: it adopts the newer one (a gap after a
//! reconnect costs nothing but the bytes). Its own commits it already holds: when the keeper
//! orders them they change nothing locally.

use std::collections::VecDeque;

use super::wire::StateId;

/// What to do with an ordered state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnOrdered {
    /// Older than (or the same as) the state held: nothing.
    Ignore,
    /// This station's own commit, now ordered: it holds it already.
    Mine,
    /// Another station's (or a state this station's commits were not made from): take its
    /// points; this station's commits waiting for the keeper will be refused.
    Adopt,
}

/// The books.
#[derive(Debug, Clone)]
pub struct Book {
    me: String,
    counter: u64,
    /// The newest ordered state taken (or made), and its version.
    held: Option<(StateId, u64)>,
    /// This station's commits the keeper has not ordered yet, oldest first.
    pending: VecDeque<StateId>,
    /// The newest version handed to the simulation to adopt: a commit the simulation made from
    /// an older one was made before it took that state, and is undone by it.
    adopted: u64,
}

impl Book {
    /// The books of station `me`, holding nothing yet; its commits are counted from `first`
    /// (a restarted station starts above its earlier counts, e.g. from the clock, so its states'
    /// names stay unique).
    pub fn new(me: &str, first: u64) -> Self {
        Self {
            me: me.to_owned(),
            counter: first.saturating_sub(1),
            held: None,
            pending: VecDeque::new(),
            adopted: 0,
        }
    }

    /// The version held (0: none).
    pub fn version(&self) -> u64 {
        self.held.as_ref().map_or(0, |h| h.1)
    }

    /// Commits waiting for the keeper.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// A local commit the simulation made on the version `base` it adopted last: its id and the
    /// state it was made from (the newest pending commit, else the state held; `None` for a
    /// scene's first state). `None` when `base` is older than a state already handed to the
    /// simulation: the commit was made before it took that state and is undone by it.
    pub fn commit(&mut self, base: u64) -> Option<(StateId, Option<StateId>)> {
        if base < self.adopted {
            return None;
        }
        self.counter += 1;
        let id = StateId {
            station: self.me.clone(),
            counter: self.counter,
        };
        let parent = self
            .pending
            .back()
            .cloned()
            .or_else(|| self.held.as_ref().map(|h| h.0.clone()));
        self.pending.push_back(id.clone());
        Some((id, parent))
    }

    /// The ordered state `id`, version `seq`, arrived.
    pub fn on_ordered(&mut self, id: &StateId, seq: u64) -> OnOrdered {
        if seq <= self.version() {
            return OnOrdered::Ignore;
        }
        self.held = Some((id.clone(), seq));
        if self.pending.front() == Some(id) {
            self.pending.pop_front();
            OnOrdered::Mine
        } else {
            // Made by someone else: every pending commit of ours was made from an older state.
            self.pending.clear();
            self.adopted = seq;
            OnOrdered::Adopt
        }
    }

    /// The version the newest pending commit will have once ordered (or the version held): a
    /// proposal names it, for a keeper that lost its state to re-seed the scene after it.
    pub fn expected_version(&self) -> u64 {
        self.version() + self.pending.len() as u64
    }

    /// The keeper's current state `id`, version `seq`, whatever the version held (the answer to
    /// a catch-up after a refusal: a restarted keeper may have numbered the scene anew).
    pub fn take_current(&mut self, id: &StateId, seq: u64) -> OnOrdered {
        if self.held.as_ref().is_some_and(|h| h.0 == *id) {
            self.held = Some((id.clone(), seq));
            return OnOrdered::Ignore;
        }
        self.held = None;
        self.on_ordered(id, seq)
    }

    /// The keeper refused this station's commit `id`: it and every later pending one (made from
    /// it) are gone; the newer state that caused it comes (or came) as an ordered state.
    pub fn on_refused(&mut self, id: &StateId) {
        if let Some(at) = self.pending.iter().position(|p| p == id) {
            self.pending.truncate(at);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(s: &str, c: u64) -> StateId {
        StateId {
            station: s.into(),
            counter: c,
        }
    }

    #[test]
    fn own_commits_chain_and_anothers_state_is_adopted() {
        let mut a = Book::new("a", 1);
        // The scene's first state, made here.
        assert_eq!(a.commit(0), Some((id("a", 1), None)));
        // Two strokes before the keeper answers: each made from the one before.
        assert_eq!(a.commit(0), Some((id("a", 2), Some(id("a", 1)))));
        assert_eq!(a.on_ordered(&id("a", 1), 1), OnOrdered::Mine);
        assert_eq!(a.commit(0), Some((id("a", 3), Some(id("a", 2)))));
        assert_eq!(a.on_ordered(&id("a", 2), 2), OnOrdered::Mine);
        // b's commit got in before a's third: adopt it; a's third will be refused.
        assert_eq!(a.on_ordered(&id("b", 1), 3), OnOrdered::Adopt);
        assert_eq!(a.pending(), 0);
        a.on_refused(&id("a", 3));
        // Duplicates and older states change nothing; the next commit is made from b's.
        assert_eq!(a.on_ordered(&id("a", 2), 2), OnOrdered::Ignore);
        assert_eq!(a.on_ordered(&id("b", 1), 3), OnOrdered::Ignore);
        // A stroke the simulation committed before it took b's state: undone by it.
        assert_eq!(a.commit(0), None);
        assert_eq!(a.commit(3), Some((id("a", 4), Some(id("b", 1)))));
        // A gap (reconnected): the newest state is all it needs.
        assert_eq!(a.on_ordered(&id("b", 5), 9), OnOrdered::Adopt);
        assert_eq!(a.version(), 9);
    }

    #[test]
    fn a_refusal_drops_the_commit_and_those_made_from_it() {
        let mut b = Book::new("b", 1);
        assert_eq!(b.on_ordered(&id("a", 1), 1), OnOrdered::Adopt);
        b.commit(1);
        b.commit(1);
        b.commit(1);
        b.on_refused(&id("b", 2));
        assert_eq!(b.pending(), 1);
        assert_eq!(b.commit(1), Some((id("b", 4), Some(id("b", 1)))));
        // A keeper that restarted empty numbered the scene anew: its state is taken anyway.
        assert_eq!(b.take_current(&id("c", 1), 1), OnOrdered::Adopt);
        assert_eq!(b.take_current(&id("c", 1), 1), OnOrdered::Ignore);
        assert_eq!(b.version(), 1);
        // Counted from where a restarted station starts.
        assert_eq!(Book::new("b", 500).commit(0), Some((id("b", 500), None)));
    }
}

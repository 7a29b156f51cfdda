//! A simulated one-way network link on a virtual clock: delay, jitter, loss, reordering and
//! duplication, seeded and deterministic.
//!
//! Sans-IO like the rest of this crate: no socket, no clock, no sleeping, no global state. The
//! owner drives it with its own `now`:
//! 1. [`SimLink::send`]`(now_ns, item)` for every packet the sender emits at `now_ns`;
//! 2. [`SimLink::deliver`]`(now_ns)` drains every item due at or before `now_ns`, earliest
//!    first (ties in send order); [`SimLink::next_due`] says when the next one will be.
//!
//! Per packet, in this order, each draw from one seeded xorshift64* stream: lost with
//! probability `loss` (nothing else happens to it); otherwise its arrival is
//! `now + delay_ns + U[0, jitter_ns]`, plus `reorder_hold_ns` with probability `reorder` (held
//! back, so later packets overtake it: counted as reordered); then with probability `duplicate`
//! a second copy is queued with its own jitter draw. Jitter alone can also reorder packets, as
//! on a real path; only deliberate hold-backs are counted. The same seed and the same calls give
//! the same deliveries, bit for bit.
//!
//! The queue is a binary heap sized at construction ([`SimLink::with_capacity`]): no allocation
//! per packet while fewer than that many are in flight (it grows, once, if more are).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// What the link does to packets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkParams {
    /// Fixed one-way delay, ns.
    pub delay_ns: u64,
    /// Extra delay drawn uniformly from `[0, jitter_ns]` per packet, ns.
    pub jitter_ns: u64,
    /// Probability a packet is lost, `[0, 1]`.
    pub loss: f64,
    /// Probability a packet is held back by `reorder_hold_ns` extra, `[0, 1]`.
    pub reorder: f64,
    /// How long a reordered packet is held back, ns.
    pub reorder_hold_ns: u64,
    /// Probability a delivered packet arrives twice, `[0, 1]`.
    pub duplicate: f64,
    /// Seed of the link's random stream.
    pub seed: u64,
}

impl Default for LinkParams {
    /// A perfect link: no delay, nothing lost, reordered or duplicated.
    fn default() -> Self {
        Self {
            delay_ns: 0,
            jitter_ns: 0,
            loss: 0.0,
            reorder: 0.0,
            reorder_hold_ns: 2_000_000,
            duplicate: 0.0,
            seed: 1,
        }
    }
}

impl LinkParams {
    /// A link with only a fixed one-way delay.
    pub fn delay(delay_ns: u64) -> Self {
        Self {
            delay_ns,
            ..Self::default()
        }
    }
}

/// What happened on a link so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkCounters {
    /// Packets given to [`SimLink::send`].
    pub sent: u64,
    /// Packets dropped.
    pub lost: u64,
    /// Extra copies queued.
    pub duplicated: u64,
    /// Packets held back so later ones overtake them.
    pub reordered: u64,
    /// Copies handed out by [`SimLink::deliver`].
    pub delivered: u64,
}

#[derive(Debug)]
struct Entry<T> {
    due_ns: u64,
    order: u64,
    item: T,
}

impl<T> PartialEq for Entry<T> {
    fn eq(&self, other: &Self) -> bool {
        (self.due_ns, self.order) == (other.due_ns, other.order)
    }
}
impl<T> Eq for Entry<T> {}
impl<T> PartialOrd for Entry<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Entry<T> {
    /// Reversed: the max-heap pops the earliest due (then the earliest queued) first.
    fn cmp(&self, other: &Self) -> Ordering {
        (other.due_ns, other.order).cmp(&(self.due_ns, self.order))
    }
}

/// One direction of a simulated link; see the module doc.
#[derive(Debug)]
pub struct SimLink<T> {
    params: LinkParams,
    queue: BinaryHeap<Entry<T>>,
    rng: u64,
    order: u64,
    counters: LinkCounters,
}

impl<T: Clone> SimLink<T> {
    /// A link with room for 1024 packets in flight before its queue grows.
    pub fn new(params: LinkParams) -> Self {
        Self::with_capacity(params, 1024)
    }

    /// A link with room for `capacity` packets in flight before its queue grows.
    pub fn with_capacity(params: LinkParams, capacity: usize) -> Self {
        Self {
            rng: splitmix64(params.seed) | 1,
            params,
            queue: BinaryHeap::with_capacity(capacity),
            order: 0,
            counters: LinkCounters::default(),
        }
    }

    /// The link's parameters.
    pub fn params(&self) -> &LinkParams {
        &self.params
    }

    /// Change the parameters from now on (packets in flight keep their arrival times; the
    /// random stream continues).
    pub fn set_params(&mut self, params: LinkParams) {
        self.params = params;
    }

    /// Counters so far.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// Copies in flight.
    pub fn in_flight(&self) -> usize {
        self.queue.len()
    }

    /// When the next copy arrives, if any is in flight.
    pub fn next_due(&self) -> Option<u64> {
        self.queue.peek().map(|e| e.due_ns)
    }

    /// Put `item` on the link at `now_ns`.
    pub fn send(&mut self, now_ns: u64, item: T) {
        let p = self.params;
        self.counters.sent += 1;
        if self.chance(p.loss) {
            self.counters.lost += 1;
            return;
        }
        let mut due = now_ns
            .saturating_add(p.delay_ns)
            .saturating_add(self.jitter());
        if self.chance(p.reorder) {
            due = due.saturating_add(p.reorder_hold_ns);
            self.counters.reordered += 1;
        }
        if self.chance(p.duplicate) {
            let again = now_ns
                .saturating_add(p.delay_ns)
                .saturating_add(self.jitter());
            self.push(again, item.clone());
            self.counters.duplicated += 1;
        }
        self.push(due, item);
    }

    /// Drain every copy due at or before `now_ns`, earliest first.
    pub fn deliver(&mut self, now_ns: u64) -> Deliver<'_, T> {
        Deliver { link: self, now_ns }
    }

    fn push(&mut self, due_ns: u64, item: T) {
        self.queue.push(Entry {
            due_ns,
            order: self.order,
            item,
        });
        self.order += 1;
    }

    fn next_u64(&mut self) -> u64 {
        // xorshift64*.
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// `true` with probability `p` (draws only when `0 < p < 1`, so a perfect link and a
    /// certain one do not consume the stream).
    fn chance(&mut self, p: f64) -> bool {
        if p <= 0.0 || p.is_nan() {
            false
        } else if p >= 1.0 {
            true
        } else {
            self.unit() < p
        }
    }

    fn jitter(&mut self) -> u64 {
        match self.params.jitter_ns {
            0 => 0,
            j => self.next_u64() % (j + 1),
        }
    }
}

/// The copies due, drained from a [`SimLink`] by [`SimLink::deliver`].
#[derive(Debug)]
pub struct Deliver<'a, T> {
    link: &'a mut SimLink<T>,
    now_ns: u64,
}

impl<T> Iterator for Deliver<'_, T> {
    type Item = T;

    fn next(&mut self) -> Option<T> {
        if self.link.queue.peek()?.due_ns > self.now_ns {
            return None;
        }
        let e = self.link.queue.pop()?;
        self.link.counters.delivered += 1;
        Some(e.item)
    }
}

/// SplitMix64: spreads a small seed over all 64 bits.
pub fn splitmix64(seed: u64) -> u64 {
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    /// Send one numbered packet per ms for `n` ms, deliver every ms; (arrival ms, number).
    fn run(params: LinkParams, n: u64) -> (Vec<(u64, u64)>, LinkCounters) {
        let mut link = SimLink::new(params);
        let mut got = Vec::new();
        for t in 0..n + 1_000 {
            if t < n {
                link.send(t * MS, t);
            }
            got.extend(link.deliver(t * MS).map(|i| (t, i)));
        }
        (got, link.counters())
    }

    #[test]
    fn delays_are_exact_without_jitter() {
        let (got, c) = run(LinkParams::delay(20 * MS), 100);
        assert_eq!(got.len(), 100);
        assert!(got.iter().all(|&(t, i)| t == i + 20), "{got:?}");
        assert_eq!(c.delivered, 100);
        assert_eq!((c.lost, c.duplicated, c.reordered), (0, 0, 0));
        // Not a nanosecond early.
        let mut link = SimLink::new(LinkParams::delay(5 * MS));
        link.send(1, 'x');
        assert_eq!(link.next_due(), Some(5 * MS + 1));
        assert_eq!(link.deliver(5 * MS).count(), 0);
        assert_eq!(link.deliver(5 * MS + 1).collect::<Vec<_>>(), ['x']);
    }

    #[test]
    fn jitter_stays_within_its_bound() {
        let p = LinkParams {
            delay_ns: 10 * MS,
            jitter_ns: 5 * MS,
            ..LinkParams::default()
        };
        let (got, _) = run(p, 2_000);
        assert_eq!(got.len(), 2_000);
        let lags: Vec<u64> = got.iter().map(|&(t, i)| t - i).collect();
        assert!(lags.iter().all(|l| (10..=15).contains(l)), "{lags:?}");
        // Delivered on the first whole ms at or after arrival: lags 11 and 15 are each a
        // fifth of the draws.
        assert!(
            lags.contains(&11) && lags.contains(&15),
            "uses the whole range"
        );
    }

    #[test]
    fn loss_fraction_matches_the_setting() {
        for loss in [0.05, 0.2, 0.5] {
            let p = LinkParams {
                loss,
                seed: 7,
                ..LinkParams::delay(MS)
            };
            let (got, c) = run(p, 20_000);
            let measured = c.lost as f64 / c.sent as f64;
            // 20 000 draws: the binomial σ is ≤ 0.0036; allow 4σ.
            assert!((measured - loss).abs() < 0.015, "{loss}: {measured}");
            assert_eq!(got.len() as u64, c.sent - c.lost);
        }
    }

    #[test]
    fn reordering_and_duplication_happen_and_are_counted() {
        let p = LinkParams {
            delay_ns: 5 * MS,
            reorder: 0.1,
            reorder_hold_ns: 3 * MS,
            duplicate: 0.1,
            seed: 3,
            ..LinkParams::default()
        };
        let (got, c) = run(p, 5_000);
        assert!(c.reordered > 400 && c.reordered < 600, "{c:?}");
        assert!(c.duplicated > 400 && c.duplicated < 600, "{c:?}");
        assert_eq!(got.len() as u64, c.sent + c.duplicated);
        let overtaken = got.windows(2).filter(|w| w[1].1 < w[0].1).count();
        assert!(overtaken as u64 >= c.reordered / 2, "{overtaken} of {c:?}");
        let mut numbers: Vec<u64> = got.iter().map(|g| g.1).collect();
        numbers.sort_unstable();
        numbers.dedup();
        assert_eq!(numbers.len(), 5_000, "every packet arrives at least once");
    }

    #[test]
    fn same_seed_same_output_other_seed_other_output() {
        let p = LinkParams {
            delay_ns: 2 * MS,
            jitter_ns: MS,
            loss: 0.2,
            reorder: 0.1,
            duplicate: 0.1,
            seed: 11,
            ..LinkParams::default()
        };
        let a = run(p, 3_000);
        assert_eq!(a, run(p, 3_000));
        assert_ne!(a.0, run(LinkParams { seed: 12, ..p }, 3_000).0);
    }

    #[test]
    fn the_queue_does_not_grow_within_its_capacity() {
        let mut link = SimLink::with_capacity(LinkParams::delay(100 * MS), 128);
        let cap = link.queue.capacity();
        for t in 0..1_000 {
            link.send(t * MS, [0u8; 64]);
            link.deliver(t * MS).for_each(drop);
        }
        assert_eq!(link.queue.capacity(), cap, "no reallocation");
        assert_eq!(link.in_flight(), 100);
    }
}

//! `applied_age_ticks` (issue 20) computed right, on a scripted virtual-clock run: the servo
//! core ticking at 1 kHz, a simulated link with a fixed delay each way, and a workstation that
//! answers every cursor at once and keeps the same books the live one does
//! (`AppliedAgeTracker`: a slot per command sent, the age read from each cursor's
//! acknowledgement). The clock steps 10 µs at a time, so a round trip shorter than a tick, one
//! between one and two ticks and one longer than two land in one bin each; a jittered link
//! splits between the two bins its round trips span, in the share the jitter predicts.

use haptics_server::device::DeviceSample;
use haptics_server::servo::{ServoCore, ServoParams, SessionEvent};
use protocol::{ForceCommand, LinkParams, LocalModel, SimLink};
use workstation::live::shared::AppliedAgeTracker;

const TICK_NS: u64 = 1_000_000;
const STEP_NS: u64 = 10_000;

/// Run `ticks` servo ticks through a link of `link` each way; the tracker's counts.
fn run(link: LinkParams, ticks: u64) -> protocol::AppliedAge {
    let mut core = ServoCore::new(ServoParams::omni_at_1khz());
    core.on_event(0, SessionEvent::Start);
    let mut up = SimLink::new(LinkParams { seed: 1, ..link });
    let mut down: SimLink<(u32, ForceCommand)> = SimLink::new(LinkParams { seed: 2, ..link });
    let tracker = AppliedAgeTracker::default();
    let mut sequence = 0u32;
    let mut now = 0;
    while now < ticks * TICK_NS {
        for (seq, cmd) in down.deliver(now) {
            core.on_command_packet(now, seq, cmd);
        }
        if now % TICK_NS == 0 {
            let out = core.tick(now, &DeviceSample::default());
            up.send(now, out.cursor);
        }
        for cursor in up.deliver(now) {
            tracker.on_cursor(&cursor);
            sequence += 1;
            tracker.sent(sequence, cursor.servo_tick);
            let cmd = ForceCommand {
                force: glam::Vec3::ZERO,
                torque: None,
                answers_sequence: cursor.servo_tick,
                answers_timestamp_ns: now,
                model: LocalModel::default(),
            };
            down.send(now, (sequence, cmd));
        }
        now += STEP_NS;
    }
    tracker.get()
}

fn one_way(delay_us: u64, jitter_us: u64) -> LinkParams {
    LinkParams {
        delay_ns: delay_us * 1_000,
        jitter_ns: jitter_us * 1_000,
        ..LinkParams::default()
    }
}

#[test]
fn every_tick_is_counted_by_the_age_of_the_command_it_applied() {
    // Round trips of 0.4, 1.4 and 2.4 ticks: the answer to tick k's cursor is applied at tick
    // k + 1, k + 2 and k + 3, so each tick's cursor says the command it applied is 1, 2 or 3
    // ticks old. The first few ticks have no command yet.
    for (delay_us, want) in [(200, 0), (700, 1), (1_200, 2)] {
        let a = run(one_way(delay_us, 0), 2_000);
        let bins = [a.next, a.two, a.three_or_more];
        let counted: u64 = bins.iter().sum::<u64>() + a.no_command;
        assert!(
            a.no_command <= 4 && bins[want] + a.no_command == counted,
            "{delay_us} µs each way: {a:?}"
        );
        // Every cursor that reached the workstation was counted once.
        assert!(counted > 1_990, "{delay_us} µs each way: {a:?}");
    }
}

#[test]
fn a_jittered_link_splits_the_ticks_as_its_round_trips_do() {
    // 300 µs each way plus up to 500 µs of jitter each way: round trips from 0.6 to 1.6 ticks.
    // A round trip under one tick is applied the next tick; the share of them is the chance
    // that two uniform draws on [0, 500] µs sum to less than 400 µs: 0.32. (Newer commands
    // supersede older ones, so a late one can be overtaken; the share of "next" can only rise
    // from that, and "≥ 3" stays empty.)
    let a = run(one_way(300, 500), 20_000).fractions();
    assert!(
        (0.30..0.40).contains(&a.next_tick) && a.three_or_more == 0.0,
        "{a:?}"
    );
    assert!(
        (a.next_tick + a.two_ticks + a.no_command - 1.0).abs() < 1e-9,
        "{a:?}"
    );
}

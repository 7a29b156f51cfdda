//! Round-trip property tests: every valid message decodes to exactly what was encoded.

use glam::{Quat, Vec3};
use proptest::prelude::*;
use protocol::control::{
    Bye, ClockPing, ClockPong, Config, EmergencyStop, ErrorCode, ErrorMessage, Hello, Percentiles,
    Stats, Welcome,
};
use protocol::packet::MAX_PACKET_BYTES;
use protocol::{
    Body, Control, CursorSample, ForceAck, ForceCommand, FrameDecoder, Inbound, LocalModel,
    ModelKind, Outbound, SessionKey,
};

fn scalar(limit: f32) -> impl Strategy<Value = f32> {
    -limit..=limit
}

fn vec3(limit: f32) -> impl Strategy<Value = Vec3> {
    (scalar(limit), scalar(limit), scalar(limit)).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn unit_vec3() -> impl Strategy<Value = Vec3> {
    vec3(1.0).prop_filter_map("non-zero", |v| v.try_normalize())
}

fn quat() -> impl Strategy<Value = Quat> {
    (vec3(1.0), scalar(1.0)).prop_filter_map("non-zero", |(v, w)| {
        let q = Quat::from_xyzw(v.x, v.y, v.z, w);
        (q.length() > 1e-3).then(|| q.normalize())
    })
}

fn cursor() -> impl Strategy<Value = CursorSample> {
    (
        vec3(100.0),
        quat(),
        vec3(100.0),
        any::<u16>(),
        vec3(1000.0),
        any::<u32>(),
        any::<(bool, bool)>(),
        proptest::option::of(any::<(u32, u64)>()),
    )
        .prop_map(
            |(
                position,
                orientation,
                velocity,
                buttons,
                output_force,
                servo_tick,
                (engaged, estop),
                ack,
            )| {
                CursorSample {
                    position,
                    orientation,
                    velocity,
                    buttons,
                    output_force,
                    servo_tick,
                    engaged,
                    estop,
                    ack: ack.map(|(sequence, arrival_ns)| ForceAck {
                        sequence,
                        arrival_ns,
                    }),
                }
            },
        )
}

fn model() -> impl Strategy<Value = LocalModel> {
    let kind = prop_oneof![
        Just(ModelKind::None),
        Just(ModelKind::Plane),
        Just(ModelKind::Anchor)
    ];
    (
        kind,
        vec3(100.0),
        unit_vec3(),
        0.0f32..=1e5,
        0.0f32..=1e3,
        0.0f32..=10.0,
        0.0f32..=10.0,
        0u32..=10_000_000,
    )
        .prop_map(
            |(kind, point, normal, stiffness, damping, friction, validity_radius, lifetime_us)| {
                LocalModel {
                    kind,
                    point,
                    normal,
                    stiffness,
                    damping,
                    friction,
                    validity_radius,
                    lifetime_us,
                }
            },
        )
}

fn force() -> impl Strategy<Value = ForceCommand> {
    (
        vec3(1000.0),
        proptest::option::of(vec3(100.0)),
        any::<u32>(),
        any::<u64>(),
        model(),
    )
        .prop_map(
            |(force, torque, answers_sequence, answers_timestamp_ns, model)| ForceCommand {
                force,
                torque,
                answers_sequence,
                answers_timestamp_ns,
                model,
            },
        )
}

fn body() -> impl Strategy<Value = Body> {
    prop_oneof![
        cursor().prop_map(Body::Cursor),
        force().prop_map(Body::Force)
    ]
}

fn text(max: usize) -> impl Strategy<Value = String> {
    proptest::string::string_regex(&format!(".{{0,{max}}}"))
        .unwrap()
        .prop_filter("byte length", move |s| s.len() <= max)
}

fn control() -> impl Strategy<Value = Control> {
    prop_oneof![
        (any::<u8>(), text(40), 1u32..=100_000).prop_map(
            |(protocol_version, client_name, requested_rate_hz)| {
                Control::Hello(Hello {
                    protocol_version,
                    client_name,
                    requested_rate_hz,
                })
            }
        ),
        (
            text(40),
            any::<u32>(),
            any::<[u8; 32]>(),
            0.0f32..10.0,
            1u32..=10_000
        )
            .prop_map(
                |(device_name, session_id, session_key, max_force_n, servo_rate_hz)| {
                    Control::Welcome(Welcome {
                        protocol_version: 1,
                        device_name,
                        dof_input: 6,
                        dof_output: 3,
                        workspace_min: [-0.1, -0.1, -0.1],
                        workspace_max: [0.1, 0.1, 0.1],
                        max_force_n,
                        max_stiffness_n_per_m: 700.0,
                        servo_rate_hz,
                        session_id,
                        session_key,
                    })
                }
            ),
        (any::<u32>(), any::<u64>())
            .prop_map(|(id, t0_ns)| Control::ClockPing(ClockPing { id, t0_ns })),
        (any::<u32>(), any::<u64>(), any::<u64>(), any::<u64>()).prop_map(
            |(id, t0_ns, t1_ns, t2_ns)| Control::ClockPong(ClockPong {
                id,
                t0_ns,
                t1_ns,
                t2_ns
            })
        ),
        (0.0f32..0.999, 0u32..500_000, 1u32..500_000, 0.0f32..50.0).prop_map(
            |(smoothing_alpha, start, extra, force_limit_n)| {
                Control::Config(Config {
                    smoothing_alpha,
                    watchdog_fade_start_us: start,
                    watchdog_zero_us: start + extra,
                    force_limit_n,
                })
            }
        ),
        (any::<u64>(), any::<u64>(), any::<[u64; 4]>(), any::<bool>()).prop_map(
            |(uptime_ns, ticks, p, engaged)| {
                Control::Stats(Stats {
                    uptime_ns,
                    ticks,
                    period_ns: Percentiles {
                        p50: p[0],
                        p99: p[1],
                        p999: p[2],
                        max: p[3],
                    },
                    engaged,
                    ..Stats::default()
                })
            }
        ),
        any::<bool>().prop_map(|engage| Control::EmergencyStop(EmergencyStop { engage })),
        text(100).prop_map(|reason| Control::Bye(Bye { reason })),
        text(100).prop_map(|message| Control::Error(ErrorMessage {
            code: ErrorCode::InvalidConfig,
            message
        })),
    ]
}

proptest! {
    #[test]
    fn packets_round_trip_sealed_and_unsealed(body in body(), session in any::<u32>(), ts in any::<u64>(), key in any::<[u8; 32]>(), keyed in any::<bool>()) {
        let key = keyed.then(|| SessionKey::from_bytes(key));
        let mut out = Outbound::new(session, key.clone());
        let mut inb = Inbound::new(session, key);
        let mut buf = [0u8; MAX_PACKET_BYTES];
        let len = out.encode(ts, body, &mut buf);
        let p = inb.accept(&buf[..len]).unwrap();
        prop_assert_eq!(p.body, body);
        prop_assert_eq!(p.timestamp_ns, ts);
        prop_assert_eq!(p.session, session);
        prop_assert_eq!(p.sequence, 0);
    }

    #[test]
    fn control_messages_round_trip(message in control()) {
        let mut d = FrameDecoder::new();
        d.push(&message.to_frame());
        prop_assert_eq!(d.next_message().unwrap(), Some(message));
        prop_assert_eq!(d.buffered(), 0);
    }

    #[test]
    fn control_stream_reassembles_across_arbitrary_splits(messages in proptest::collection::vec(control(), 1..8), cut in any::<prop::sample::Index>()) {
        let stream: Vec<u8> = messages.iter().flat_map(|m| m.to_frame()).collect();
        let at = cut.index(stream.len() + 1);
        let mut d = FrameDecoder::new();
        let mut got = Vec::new();
        for chunk in [&stream[..at], &stream[at..]] {
            d.push(chunk);
            while let Some(m) = d.next_message().unwrap() {
                got.push(m);
            }
        }
        prop_assert_eq!(got, messages);
    }
}

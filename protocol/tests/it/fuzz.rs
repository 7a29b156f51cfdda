//! Bounded fuzzing of every decoder: random bytes and mutations of valid messages.
//!
//! 1,200,000 inputs in all (600,000 hot-path packets, 600,000 control frames), seeded so a
//! failure replays. The property: no input panics, and whatever is accepted is valid.

use protocol::control::MAX_FRAME_BYTES;
use protocol::packet::MAX_PACKET_BYTES;
use protocol::{Body, Control, FrameDecoder, Inbound, Outbound, Packet};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::examples;

const PACKET_INPUTS: usize = 600_000;
const CONTROL_INPUTS: usize = 600_000;

fn mutate(rng: &mut ChaCha8Rng, bytes: &mut Vec<u8>) {
    for _ in 0..rng.random_range(1..=4) {
        match rng.random_range(0..6) {
            0 if !bytes.is_empty() => {
                let i = rng.random_range(0..bytes.len());
                bytes[i] ^= 1 << rng.random_range(0..8);
            }
            1 if !bytes.is_empty() => {
                let i = rng.random_range(0..bytes.len());
                bytes[i] = rng.random();
            }
            2 => bytes.truncate(rng.random_range(0..=bytes.len())),
            3 => bytes.push(rng.random()),
            4 if bytes.len() >= 4 => {
                // Splice in an interesting float: NaN, inf, huge, denormal.
                let specials = [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, -1e-40, 0.0];
                let v = specials[rng.random_range(0..specials.len())].to_le_bytes();
                let i = rng.random_range(0..=bytes.len() - 4);
                bytes[i..i + 4].copy_from_slice(&v);
            }
            _ => {}
        }
    }
}

#[test]
fn hot_path_decoders_never_panic_and_accept_only_valid_packets() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0001);
    let seeds: Vec<Vec<u8>> = [
        Body::Cursor(examples::cursor()),
        Body::Force(examples::force()),
    ]
    .into_iter()
    .flat_map(|body| {
        [true, false].map(|keyed| {
            let mut out = Outbound::new(examples::SESSION, keyed.then(examples::key));
            let mut buf = [0u8; MAX_PACKET_BYTES];
            let len = out.encode(1, body, &mut buf);
            buf[..len].to_vec()
        })
    })
    .collect();
    let mut accepted = 0usize;
    for i in 0..PACKET_INPUTS {
        let mut bytes = if i % 4 == 0 {
            let len = rng.random_range(0..=MAX_PACKET_BYTES + 8);
            (0..len).map(|_| rng.random()).collect()
        } else {
            seeds[i % seeds.len()].clone()
        };
        if i % 4 != 0 {
            mutate(&mut rng, &mut bytes);
        }
        // Unkeyed decoding reaches the value checks; keyed exercises the MAC path.
        if let Ok(p) = Packet::decode(&bytes) {
            assert_eq!(p.validate(), Ok(()));
            accepted += 1;
        }
        let mut keyed = Inbound::new(examples::SESSION, Some(examples::key()));
        if let Ok(p) = keyed.accept(&bytes) {
            assert_eq!(p.validate(), Ok(()));
        }
    }
    // The mutations must leave some inputs valid, or the value checks were never reached.
    assert!(
        accepted > 1000,
        "only {accepted} inputs decoded: the fuzzer is not reaching deep"
    );
}

#[test]
fn control_decoder_never_panics() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0002);
    let seeds: Vec<Vec<u8>> = examples::controls()
        .iter()
        .map(|(_, m)| m.to_frame())
        .collect();
    let mut decoded = 0usize;
    for i in 0..CONTROL_INPUTS {
        let mut bytes = if i % 4 == 0 {
            let len = rng.random_range(0..64);
            (0..len).map(|_| rng.random()).collect()
        } else {
            seeds[i % seeds.len()].clone()
        };
        if i % 4 != 0 {
            mutate(&mut rng, &mut bytes);
        }
        let mut d = FrameDecoder::new();
        d.push(&bytes);
        // Drain until the decoder needs more bytes or gives up.
        for _ in 0..8 {
            match d.next_message() {
                Ok(Some(m)) => {
                    assert_eq!(m.validate(), Ok(()));
                    decoded += 1;
                }
                Ok(None) => break,
                Err(protocol::control::ControlError::FrameTooLarge { len }) => {
                    assert!(len > MAX_FRAME_BYTES);
                    break;
                }
                Err(_) => {}
            }
        }
        let _ = Control::from_payload(&bytes);
    }
    assert!(
        decoded > 1000,
        "only {decoded} frames decoded: the fuzzer is not reaching deep"
    );
}

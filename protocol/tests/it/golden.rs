//! Golden byte vectors: the wire format cannot change without these files changing.
//!
//! `UPDATE_GOLDEN=1 cargo test -p protocol golden` rewrites the files (review the diff!).
//! The sealed packet examples in `docs/PROTOCOL.md` are decoded here too, so the document and
//! the code cannot drift apart.

use std::path::PathBuf;

use protocol::packet::MAX_PACKET_BYTES;
use protocol::{Body, Control, Inbound, Outbound, Packet};

use crate::examples;

fn golden_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(format!("{name}.hex"))
}

fn to_hex(bytes: &[u8]) -> String {
    let mut out = String::new();
    for (i, b) in bytes.iter().enumerate() {
        out.push_str(&format!("{b:02x}"));
        out.push(if i % 16 == 15 { '\n' } else { ' ' });
    }
    out.trim_end().to_string() + "\n"
}

fn from_hex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).unwrap_or_else(|_| panic!("bad hex byte {h:?}")))
        .collect()
}

fn check_golden(name: &str, bytes: &[u8]) {
    let path = golden_path(name);
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, to_hex(bytes)).unwrap();
        return;
    }
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (run with UPDATE_GOLDEN=1 to create)",
            path.display()
        )
    });
    assert_eq!(
        from_hex(&text),
        bytes,
        "wire bytes of {name} changed; if intended, bump PROTOCOL_VERSION, rerun with \
         UPDATE_GOLDEN=1 and update docs/PROTOCOL.md"
    );
}

fn sealed(sequence: u32, timestamp_ns: u64, body: Body, keyed: bool) -> Vec<u8> {
    let key = keyed.then(examples::key);
    let mut out = Outbound::new(examples::SESSION, key);
    for _ in 0..sequence {
        out.encode(0, body, &mut [0; MAX_PACKET_BYTES]);
    }
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let len = out.encode(timestamp_ns, body, &mut buf);
    buf[..len].to_vec()
}

#[test]
fn hot_path_packets_match_golden_bytes() {
    for (name, seq, ts, body) in examples::packets() {
        check_golden(&format!("{name}_quic"), &sealed(seq, ts, body, false));
        check_golden(&format!("{name}_udp"), &sealed(seq, ts, body, true));
    }
}

#[test]
fn control_frames_match_golden_bytes() {
    for (name, message) in examples::controls() {
        check_golden(&format!("control_{name}"), &message.to_frame());
    }
}

#[test]
fn golden_files_decode_to_the_examples() {
    for (name, seq, ts, body) in examples::packets() {
        let bytes =
            from_hex(&std::fs::read_to_string(golden_path(&format!("{name}_udp"))).unwrap());
        let mut inbound = Inbound::new(examples::SESSION, Some(examples::key()));
        let p = inbound.accept(&bytes).expect("golden packet decodes");
        let want = Packet {
            session: examples::SESSION,
            sequence: seq,
            timestamp_ns: ts,
            body,
        };
        assert_eq!(p, want, "{name}");
    }
    for (name, message) in examples::controls() {
        let bytes =
            from_hex(&std::fs::read_to_string(golden_path(&format!("control_{name}"))).unwrap());
        let mut decoder = protocol::FrameDecoder::new();
        decoder.push(&bytes);
        assert_eq!(decoder.next_message().unwrap(), Some(message), "{name}");
    }
}

/// Fenced blocks in `docs/PROTOCOL.md` opened with "```hex NAME".
fn documented_examples() -> Vec<(String, Vec<u8>)> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/PROTOCOL.md");
    let doc = std::fs::read_to_string(&path).expect("docs/PROTOCOL.md exists");
    let mut found = Vec::new();
    let mut lines = doc.lines();
    while let Some(line) = lines.next() {
        if let Some(name) = line.strip_prefix("```hex ") {
            let body: Vec<&str> = lines
                .by_ref()
                .take_while(|l| !l.starts_with("```"))
                .collect();
            found.push((name.trim().to_string(), from_hex(&body.join("\n"))));
        }
    }
    found
}

#[test]
fn protocol_doc_examples_decode_to_the_documented_values() {
    let docs = documented_examples();
    let names: Vec<&str> = docs.iter().map(|(n, _)| n.as_str()).collect();
    for want in ["cursor_udp", "force_udp", "control_hello"] {
        assert!(
            names.contains(&want),
            "docs/PROTOCOL.md lacks the {want} example: {names:?}"
        );
    }
    for (name, bytes) in docs {
        match name.as_str() {
            "cursor_udp" | "force_udp" => {
                let mut inbound = Inbound::new(examples::SESSION, Some(examples::key()));
                let p = inbound
                    .accept(&bytes)
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
                let (_, seq, ts, body) = examples::packets()
                    .into_iter()
                    .find(|(n, ..)| name.starts_with(n))
                    .unwrap();
                assert_eq!(
                    (p.sequence, p.timestamp_ns, p.body),
                    (seq, ts, body),
                    "{name}"
                );
            }
            other => {
                let control = other.strip_prefix("control_").expect("known example name");
                let (_, want) = examples::controls()
                    .into_iter()
                    .find(|(n, _)| *n == control)
                    .unwrap();
                let mut decoder = protocol::FrameDecoder::new();
                decoder.push(&bytes);
                let got: Option<Control> = decoder.next_message().unwrap();
                assert_eq!(got, Some(want), "{name}");
            }
        }
    }
}

#!/usr/bin/env python3
"""Decode haptic-sculpt hot-path packets, written from docs/PROTOCOL.md alone (stdlib only).

Usage: hp_packet.py HEXFILE [--mac]   prints the decoded packet as JSON.
With --mac the last 16 bytes are treated as the UDP MAC and stripped (not verified: the
standard library has no BLAKE3; a real client would use the `blake3` package).
"""
import json
import struct
import sys

HEADER = struct.Struct("<2sBBHIIQ")  # magic, version, kind, flags, session, sequence, timestamp_ns
CURSOR = struct.Struct("<3f4f3f3fIHIQ")  # position, orientation xyzw, velocity, output_force, tick, buttons, ack seq, ack arrival
FORCE = struct.Struct("<3f3fIQ3f3fffffI")  # force, torque, answers seq/ts, point, normal, k, b, mu, radius, lifetime


def decode(data: bytes) -> dict:
    magic, version, kind, flags, session, sequence, timestamp_ns = HEADER.unpack_from(data)
    if magic != b"HP":
        raise ValueError(f"bad magic {magic!r}")
    if version != 3:
        raise ValueError(f"unsupported version {version}")
    out = {"kind": kind, "flags": flags, "session": session, "sequence": sequence,
           "timestamp_ns": timestamp_ns}
    body = data[HEADER.size:]
    if kind == 1:
        if len(body) != CURSOR.size:
            raise ValueError(f"cursor body is {len(body)} bytes, expected {CURSOR.size}")
        v = CURSOR.unpack(body)
        out.update(position=v[0:3], orientation=v[3:7], velocity=v[7:10], output_force=v[10:13],
                   servo_tick=v[13], buttons=v[14], engaged=bool(flags & 1), estop=bool(flags & 2),
                   ack={"sequence": v[15], "arrival_ns": v[16]} if flags & 4 else None)
    elif kind == 2:
        if len(body) != FORCE.size:
            raise ValueError(f"force body is {len(body)} bytes, expected {FORCE.size}")
        v = FORCE.unpack(body)
        model = {0: "none", 2: "plane", 4: "anchor"}[flags & 0b110]
        out.update(force=v[0:3], torque=v[3:6] if flags & 1 else None, answers_sequence=v[6],
                   answers_timestamp_ns=v[7], model=model, point=v[8:11], normal=v[11:14],
                   stiffness=v[14], damping=v[15], friction=v[16], validity_radius=v[17],
                   lifetime_us=v[18])
    else:
        raise ValueError(f"unknown kind {kind}")
    return out


def main() -> None:
    data = bytes.fromhex(open(sys.argv[1]).read())
    if "--mac" in sys.argv[2:]:
        data = data[:-16]
    print(json.dumps(decode(data)))


if __name__ == "__main__":
    main()

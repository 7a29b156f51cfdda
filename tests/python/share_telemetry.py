#!/usr/bin/env python3
"""Record the telemetry of a shared scene and summarise it per station as JSON.

Usage:
    share_telemetry.py --connect ENDPOINT --scene SCENE --seconds S --out FILE.json
                       [--ca ROUTER.pem --cert ME.pem --key ME.key]
                       [--open-timeout S] [--print]

Every station of a shared scene publishes its telemetry 125 times a second on
`haptic-sculpt/<SCENE>/telemetry/<STATION>`, one UTF-8 JSON object per sample:

    {"station": "a", "t_ns": 123, "cursor": [x, y, z] or null, "force": [fx, fy, fz],
     "buttons": 0, "tool": "rope" or null, "force_loop_hz": 1000.0, "sim_hz": 500.0,
     "rtt_us": 350.0, "version": 3}

(`t_ns` is the station's own monotonic clock; `version` the scene version it holds.)

This script joins the scene's router as a Zenoh client (`--connect tcp/HOST:PORT` or
`tls/HOST:PORT`; multicast scouting off, as every station has it), subscribes
`haptic-sculpt/<SCENE>/telemetry/*`, records for S seconds from the first sample that arrives
(S seconds in all when none does), and writes FILE.json:

    {"stations": {"<STATION>": {"samples": N, "first_t_ns": ..., "last_t_ns": ...,
                                "rate_hz": (N-1) / ((last_t_ns - first_t_ns) / 1e9),
                                "malformed": M, "max_version": V, "last": {<last sample>}}},
     "seconds": S}

Only well-formed samples count in `samples`, the times, the rate, `max_version` and `last`;
`first_t_ns` and `last_t_ns` are those of the first and last well-formed sample received.
Values that cannot be computed (no sample, or one only for the rate) are null. A payload that
is not UTF-8 JSON, not an object, lacks a field, has a field of the wrong type, or names
another station than its key counts in that station's `malformed` (the key's last chunk
names the station) and is otherwise ignored. Fields beyond those above are allowed.

A `tls/` endpoint needs the station's mutual-TLS files, as `workstation share-identity` makes
them: `--ca` the router's certificate (the host in `tls/HOST:PORT` must be one of its names,
as for the stations), `--cert` and `--key` a certificate the router lists and its key.

`--print` also prints each sample as a line for people. Ctrl-C ends the recording early:
the file is still written and the exit status is 130.

Exit status: 0 when FILE.json was written; 2 on a usage error or when the session cannot be
opened within `--open-timeout` seconds (no router there, a refused TLS handshake), with the
reason on stderr; 1 when zenoh is not installed or FILE.json cannot be written.

Needs Zenoh's Python binding (`eclipse-zenoh`, the release of the Rust crate): `.ci/setup`
installs it into the venv at $HAPTIC_SCULPT_PYENV, or else ~/.cache/haptic-sculpt/pyzenoh,
so run this script with that venv's `bin/python`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import queue
import re
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = "haptic-sculpt"
"""The first chunk of every key of the shared scenes."""

NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}")
"""A scene's or a station's name (the workstation's rule: letters, digits, - _ .)."""

ENDPOINT = re.compile(r"(tcp|tls)/(\S+):(\d+)")
"""An endpoint as users write them: tcp/HOST:PORT or tls/HOST:PORT."""

EXIT_FAILED = 1
EXIT_NO_SESSION = 2
EXIT_INTERRUPTED = 130


# ---------------------------------------------------------------------------------------------
# Samples


def _is_number(v: Any) -> bool:
    if isinstance(v, bool):
        return False
    return isinstance(v, int) or (isinstance(v, float) and math.isfinite(v))


def _is_uint(v: Any, limit: int | None = None) -> bool:
    if isinstance(v, bool) or not isinstance(v, int):
        return False
    return 0 <= v and (limit is None or v <= limit)


def _is_vec3(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 3 and all(_is_number(x) for x in v)


FIELDS = {
    "station": lambda v: isinstance(v, str),
    "t_ns": _is_uint,
    "cursor": lambda v: v is None or _is_vec3(v),
    "force": _is_vec3,
    "buttons": lambda v: _is_uint(v, 0xFFFF),
    "tool": lambda v: v is None or isinstance(v, str),
    "force_loop_hz": _is_number,
    "sim_hz": _is_number,
    "rtt_us": _is_number,
    "version": _is_uint,
}
"""Each field of a telemetry sample and the check of its value."""


def parse_sample(payload: bytes, station: str) -> tuple[dict | None, str | None]:
    """The sample in `payload` published under `station`'s key, or why it is malformed."""
    try:
        obj = json.loads(payload.decode("utf-8"))
    except UnicodeDecodeError:
        return None, "not UTF-8"
    except ValueError as e:
        return None, f"not JSON ({e})"
    if not isinstance(obj, dict):
        return None, f"not a JSON object but {type(obj).__name__}"
    for name, ok in FIELDS.items():
        if name not in obj:
            return None, f"no `{name}`"
        if not ok(obj[name]):
            return None, f"`{name}` is {json.dumps(obj[name])}"
    if obj["station"] != station:
        return None, f"`station` is {json.dumps(obj['station'])} under {station}'s key"
    return obj, None


def format_sample(s: dict) -> str:
    """One line for people."""

    def vec(v: list | None, digits: int, unit: str) -> str:
        return "-" if v is None else "(" + ", ".join(f"{x:+.{digits}f}" for x in v) + f") {unit}"

    return (
        f"{s['station']:<12} t={s['t_ns'] / 1e9:12.6f}s  cursor={vec(s['cursor'], 4, 'm')}  "
        f"force={vec(s['force'], 3, 'N')}  buttons={s['buttons']:#06x}  tool={s['tool'] or '-'}  "
        f"loop={s['force_loop_hz']:.0f} Hz  sim={s['sim_hz']:.0f} Hz  rtt={s['rtt_us']:.0f} us  "
        f"v{s['version']}"
    )


@dataclass
class StationLog:
    """What was recorded of one station."""

    samples: int = 0
    malformed: int = 0
    first_t_ns: int | None = None
    last_t_ns: int | None = None
    max_version: int | None = None
    last: dict | None = None

    def add(self, sample: dict) -> None:
        """Count a well-formed sample."""
        self.samples += 1
        if self.first_t_ns is None:
            self.first_t_ns = sample["t_ns"]
        self.last_t_ns = sample["t_ns"]
        v = sample["version"]
        self.max_version = v if self.max_version is None else max(self.max_version, v)
        self.last = sample

    def summary(self) -> dict:
        """The station's entry in the output file."""
        rate = None
        if self.samples >= 2 and self.last_t_ns > self.first_t_ns:
            rate = (self.samples - 1) / ((self.last_t_ns - self.first_t_ns) / 1e9)
        return {
            "samples": self.samples,
            "first_t_ns": self.first_t_ns,
            "last_t_ns": self.last_t_ns,
            "rate_hz": rate,
            "malformed": self.malformed,
            "max_version": self.max_version,
            "last": self.last,
        }


# ---------------------------------------------------------------------------------------------
# The session


def client_config(zenoh: Any, args: argparse.Namespace) -> Any:
    """The Zenoh client configuration for `args`, as the workstation's own (share/bus.rs)."""
    c = zenoh.Config()

    def put(key: str, value: Any) -> None:
        c.insert_json5(key, json.dumps(value))

    put("mode", "client")
    # Sites are linked by naming endpoints, never by multicast discovery.
    put("scouting/multicast/enabled", False)
    put("scouting/gossip/enabled", False)
    put("connect/endpoints", [args.connect])
    # Keep trying to reach the router for this long, then give up (the workstation's stations
    # wait forever; a recorder in a test must fail instead).
    put("connect/timeout_ms", round(args.open_timeout * 1000))
    put("connect/exit_on_failure", True)
    if args.connect.startswith("tls/"):
        k = "transport/link/tls"
        put(f"{k}/root_ca_certificate", str(args.ca))
        put(f"{k}/connect_certificate", str(args.cert))
        put(f"{k}/connect_private_key", str(args.key))
        put(f"{k}/enable_mtls", True)
        # Zenoh 1.10 trusts the public web PKI roots beside the router's certificate, so its
        # name is checked too (as the stations do): the endpoint's host must be one of the
        # router certificate's names (`share-identity router --host NAME`).
        put(f"{k}/verify_name_on_connect", True)
    return c


def record(session: Any, args: argparse.Namespace) -> tuple[dict[str, StationLog], bool]:
    """Record the scene's telemetry as `args` say: the logs by station, and whether Ctrl-C
    ended the recording early."""
    from zenoh import SampleKind

    logs: dict[str, StationLog] = {}
    printing = args.print

    def show(line: str) -> None:
        nonlocal printing
        try:
            print(line, flush=True)
        except BrokenPipeError:  # the reader left (`| head`): go on recording, silently
            printing = False
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())

    def take(key: str, payload: bytes, kind: Any) -> None:
        if kind != SampleKind.PUT:
            return  # a delete carries no telemetry
        station = key.rsplit("/", 1)[-1]  # the subscription's `*`: one chunk, the station
        log = logs.setdefault(station, StationLog())
        sample, why = parse_sample(payload, station)
        if sample is None:
            log.malformed += 1
            if printing:
                show(f"{station:<12} malformed: {why}")
            return
        log.add(sample)
        if printing:
            show(format_sample(sample))

    # Zenoh calls back on its own threads: hand each sample over with its arrival time and do
    # the work here, so a slow terminal never holds up the session.
    inbox: queue.SimpleQueue = queue.SimpleQueue()

    def on_sample(sample: Any) -> None:
        inbox.put((time.monotonic(), str(sample.key_expr), sample.payload.to_bytes(), sample.kind))

    subscriber = session.declare_subscriber(f"{ROOT}/{args.scene}/telemetry/*", on_sample)
    deadline = time.monotonic() + args.seconds  # until the first sample: S seconds in all
    first = True
    interrupted = False
    try:
        while True:
            try:
                item = inbox.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            arrived, key, payload, kind = item
            if first:  # S seconds from the first sample
                deadline = arrived + args.seconds
                first = False
            if arrived > deadline:
                break
            take(key, payload, kind)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        subscriber.undeclare()
    if not interrupted:  # samples that arrived in time but were still queued
        while True:
            try:
                arrived, key, payload, kind = inbox.get_nowait()
            except queue.Empty:
                break
            if arrived <= deadline:
                take(key, payload, kind)
    return logs, interrupted


def write_json(path: Path, value: dict) -> None:
    """Write `value` to `path` whole or not at all (a reader never sees half a file)."""
    path = path.resolve()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(value, f, indent=2)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


# ---------------------------------------------------------------------------------------------
# Command line


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line, checked (a usage error exits with status 2)."""
    p = argparse.ArgumentParser(
        description="Record a shared scene's telemetry and summarise it per station.",
        epilog="Exit status: 0 written; 2 usage error or no session; 1 other failure; 130 Ctrl-C.",
    )
    arg = p.add_argument
    arg("--connect", required=True, metavar="ENDPOINT", help="the router: tcp/ or tls/HOST:PORT")
    arg("--scene", required=True, help="the scene's name")
    arg("--seconds", required=True, type=float, metavar="S", help="how long, from the first sample")
    arg("--out", required=True, type=Path, metavar="FILE.json", help="where to write the summary")
    arg("--ca", type=Path, metavar="ROUTER.pem", help="the router's certificate (tls/ only)")
    arg("--cert", type=Path, metavar="ME.pem", help="this recorder's certificate (tls/ only)")
    arg("--key", type=Path, metavar="ME.key", help="its private key (tls/ only)")
    arg("--open-timeout", type=float, default=5.0, metavar="S",
        help="how long to keep trying to reach the router (default 5; 0: one try)")
    arg("--print", action="store_true", help="print each sample as a line")
    args = p.parse_args(argv)

    if not ENDPOINT.fullmatch(args.connect):
        p.error(f"--connect {args.connect}: expected tcp/HOST:PORT or tls/HOST:PORT")
    if not NAME.fullmatch(args.scene):
        p.error(f"--scene {args.scene!r}: a scene's name is 1 to 64 letters, digits, - _ .")
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        p.error("--seconds must be a positive number")
    if not (math.isfinite(args.open_timeout) and args.open_timeout >= 0):
        p.error("--open-timeout must be 0 or more")
    tls_files = {"--ca": args.ca, "--cert": args.cert, "--key": args.key}
    if args.connect.startswith("tls/"):
        missing = [flag for flag, path in tls_files.items() if path is None]
        if missing:
            p.error(
                f"{args.connect} is a TLS endpoint: give --ca (the router's certificate), "
                f"--cert and --key (missing {', '.join(missing)})"
            )
        for flag, path in tls_files.items():
            if not path.is_file():
                p.error(f"{flag} {path}: no such file")
    elif any(path is not None for path in tls_files.values()):
        p.error(f"--ca/--cert/--key need a tls/ endpoint (got {args.connect})")
    if not args.out.resolve().parent.is_dir():
        p.error(f"--out {args.out}: its folder does not exist")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        import zenoh
    except ImportError as e:
        print(
            f"share_telemetry: cannot import zenoh ({e}): run .ci/setup and use the python of "
            "its venv ($HAPTIC_SCULPT_PYENV, or else ~/.cache/haptic-sculpt/pyzenoh)",
            file=sys.stderr,
        )
        return EXIT_FAILED

    try:
        session = zenoh.open(client_config(zenoh, args))
    except Exception as e:  # zenoh.ZError, but any failure to open means the same here
        print(f"share_telemetry: no Zenoh session to {args.connect}: {e}", file=sys.stderr)
        if args.connect.startswith("tls/"):
            print(
                "share_telemetry: (a router that refuses the handshake looks the same: is --cert "
                "in its authorized list, and --ca its certificate?)",
                file=sys.stderr,
            )
        return EXIT_NO_SESSION
    try:
        logs, interrupted = record(session, args)
    finally:
        session.close()

    result = {
        "stations": {name: logs[name].summary() for name in sorted(logs)},
        "seconds": args.seconds,
    }
    try:
        write_json(args.out, result)
    except OSError as e:
        print(f"share_telemetry: cannot write {args.out}: {e}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_INTERRUPTED if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())

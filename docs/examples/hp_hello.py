#!/usr/bin/env python3
"""Open a session with a haptics-server over the UDP transport's control channel, written from
docs/PROTOCOL.md alone (standard library only): TLS 1.3 with ALPN `haptics/1`, the server's
certificate pinned, this workstation's client certificate presented; then `Hello`, and the
server's answer printed as JSON.

Usage: hp_hello.py HOST PORT SERVER_CERT.pem [CLIENT.pem CLIENT.key]
Prints {"answer": "Welcome", "session_id": ..., "servo_rate_hz": ...} or
{"answer": "Error", "code": N, "message": "..."}.
"""
import json
import socket
import ssl
import struct
import sys


def varint(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def read_varint(buf: bytes, i: int):
    n, shift = 0, 0
    while True:
        b = buf[i]
        i += 1
        n |= (b & 0x7F) << shift
        shift += 7
        if not b & 0x80:
            return n, i


def read_exact(tls, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = tls.recv(n - len(data))
        if not chunk:
            raise ConnectionError("the server closed the connection")
        data += chunk
    return data


def main() -> None:
    host, port, server_cert = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_3
    # Pinning: no CA and no name check; the certificate must be exactly the pinned one.
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    ctx.set_alpn_protocols(["haptics/1"])
    if len(sys.argv) >= 6:
        ctx.load_cert_chain(sys.argv[4], sys.argv[5])
    pinned = ssl.PEM_cert_to_DER_cert(open(server_cert).read())
    with socket.create_connection((host, port), timeout=5) as raw:
        with ctx.wrap_socket(raw, server_hostname="haptics-server") as tls:
            if tls.getpeercert(binary_form=True) != pinned:
                raise SystemExit("the server's certificate is not the pinned one")
            if tls.selected_alpn_protocol() != "haptics/1":
                raise SystemExit("no ALPN haptics/1")
            name = b"python"
            # Control::Hello = variant 0: protocol_version u8, client_name string, rate varint.
            hello = varint(0) + bytes([3]) + varint(len(name)) + name + varint(1000)
            tls.sendall(struct.pack("<I", len(hello)) + hello)
            (length,) = struct.unpack("<I", read_exact(tls, 4))
            msg = read_exact(tls, length)
            variant, i = read_varint(msg, 0)
            if variant == 1:  # Welcome
                i += 1  # protocol_version
                n, i = read_varint(msg, i)
                device = msg[i:i + n].decode()
                i += n + 2 + 24 + 8  # dof_input, dof_output, workspace min/max, limits
                rate, i = read_varint(msg, i)
                session, i = read_varint(msg, i)
                print(json.dumps({"answer": "Welcome", "device": device, "servo_rate_hz": rate,
                                  "session_id": session}))
            elif variant == 8:  # Error
                code, i = read_varint(msg, i)
                n, i = read_varint(msg, i)
                print(json.dumps({"answer": "Error", "code": code,
                                  "message": msg[i:i + n].decode()}))
            else:
                print(json.dumps({"answer": f"variant {variant}"}))


if __name__ == "__main__":
    main()

"""wire.py - Tessera's frames for the Python bench clients (docs/protocol.md):
u32 little-endian length (kind byte + body), the kind byte, the body."""
import json
import struct


def frame(kind, body):
    """The bytes of one frame of kind (b"J", b"S", ...) holding body."""
    return struct.pack("<I", len(body) + 1) + kind + body


def json_frame(obj):
    """The bytes of a JSON frame holding obj."""
    return frame(b"J", json.dumps(obj).encode())


def read_frame(s):
    """One frame from socket s as (kind byte, body). Raises EOFError when the
    peer closes mid-way, OSError on a reset or timeout."""
    hdr = b""
    while len(hdr) < 5:
        c = s.recv(5 - len(hdr))
        if not c:
            raise EOFError
        hdr += c
    n = struct.unpack("<I", hdr[:4])[0] - 1
    body = b""
    while len(body) < n:
        c = s.recv(min(1 << 20, n - len(body)))
        if not c:
            raise EOFError
        body += c
    return hdr[4:5], body

"""atheris target: LZF streams through scanalign.io.lzf_decompress (bytes 0-3: the expected
output size, little-endian, reduced modulo 1 MiB + 1; the rest: the stream)."""

from __future__ import annotations

import struct

import _fuzzlib

with _fuzzlib.instrumented():
    from scanalign import io


def seeds() -> dict:
    text = b"abcabcabcabcabcabc, a repeated pattern: abcabcabc"
    literal = bytes([len(text) - 1]) + text
    back_references = b"\x02abc" + b"\xe0\x05\x02" + b"\x00x" + b"\x20\x00"  # literal, long match, overlap
    return {"literal": struct.pack("<I", len(text)) + literal,
            "matches": struct.pack("<I", 3 + 14 + 1 + 3) + back_references,
            "empty": struct.pack("<I", 0)}


def test_one_input(data: bytes) -> None:
    if len(data) < 4:
        return
    expected = struct.unpack("<I", data[:4])[0] % ((1 << 20) + 1)
    try:
        out = io.lzf_decompress(data[4:], expected)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    _fuzzlib.outcome(f"ok {min(len(data) // 16, 16)}")
    assert isinstance(out, bytes) and len(out) == expected, (len(out), expected)


if __name__ == "__main__":
    _fuzzlib.run(test_one_input, seeds())

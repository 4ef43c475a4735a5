"""An export's bytes as lines: plain or gzip, cut into chunks anywhere, never silently short."""

from __future__ import annotations

import gzip
import re

import pytest

from trajcache.services.errors import InvalidInputError, PayloadTooLargeError
from trajcache.services.maintenance.reading import export_lines

TEXT = '\ufeff{"a":1}\r\n{"b":"x\u2028y"}\n\nlast'.encode()
LINES = ['{"a":1}', '{"b":"x\u2028y"}', "", "last"]


def read(data: bytes, chunk: int | None = None, **kw: int) -> list[str]:
    size = chunk or max(len(data), 1)
    chunks = [data[i : i + size] for i in range(0, len(data), size)]
    return list(export_lines(chunks=chunks, what="file", **kw))


@pytest.mark.parametrize("chunk", [None, 1, 3])
def test_plain_gzip_and_concatenated_gzip_read_the_same_lines(chunk: int | None) -> None:
    assert read(TEXT, chunk) == LINES
    assert read(gzip.compress(TEXT), chunk) == LINES
    two = gzip.compress(TEXT[:12]) + gzip.compress(TEXT[12:])
    assert read(two, chunk) == LINES


@pytest.mark.parametrize("chunk", [None, 1, 5])
def test_corrupt_truncated_or_empty_input_is_refused(chunk: int | None) -> None:
    packed = gzip.compress(TEXT)
    cases = {
        packed[:-4]: f"gzip stream truncated after {len(packed) - 4} bytes",
        packed[:10]: "gzip stream truncated after 10 bytes",
        packed + b"x": f"data after the gzip stream ends (byte {len(packed) + 1})",
        packed[:-8] + bytes(8): "incorrect data check",
        b"\x1f\x8bnot gzip": "not valid gzip within the first",
        b"ok\n\xff\n": "line 2: not UTF-8 text (byte 1 of the line)",
        b"": "empty file: nothing to import",
        b" \r\n\n": "empty file: nothing to import",
        gzip.compress(b""): "empty file: nothing to import",
    }
    for data, message in cases.items():
        with pytest.raises(InvalidInputError, match=re.escape(message)):
            read(data, chunk)


def test_the_unpacked_size_is_bounded() -> None:
    bomb = gzip.compress(b"\n" * 100_000)
    with pytest.raises(PayloadTooLargeError, match="unpacked file is larger"):
        read(bomb, max_bytes=1000)
    assert len(read(gzip.compress(b"x\n" * 500), max_bytes=1000)) == 500

"""Reading an export's bytes as lines for import: plain or gzip, UTF-8, nothing cut short.

`POST /v1/admin/import` and `trajcache import` both read through `export_lines`. Input is never
silently shortened: a gzip stream that is corrupt or ends before its trailer, a line that is not
UTF-8 and input without a single non-blank line are InvalidInputErrors naming the byte or the
line. The unpacked size can be bounded (no decompression bombs). Lines end at `\\n` (or `\\r\\n`)
only, so a U+2028 inside a JSON string does not split its line.
"""

from __future__ import annotations

import itertools
import zlib
from collections.abc import Iterable, Iterator

from trajcache.services.errors import InvalidInputError, PayloadTooLargeError

GZIP_MAGIC = b"\x1f\x8b"
_GZIP_WBITS = 16 + zlib.MAX_WBITS
CHUNK_BYTES = 1 << 16


def export_lines(
    *, chunks: Iterable[bytes], what: str = "body", max_bytes: int | None = None
) -> Iterator[str]:
    """The lines of an export read as byte chunks (see the module docstring)."""
    seen = False
    number = 0
    for number, raw in enumerate(_split(_unpacked(chunks, what, max_bytes)), start=1):
        try:
            text = raw.removesuffix(b"\r").decode("utf-8-sig" if number == 1 else "utf-8")
        except UnicodeDecodeError as exc:
            raise InvalidInputError(
                f"line {number}: not UTF-8 text (byte {exc.start + 1} of the line)"
            ) from None
        seen = seen or bool(text.strip())
        yield text
    if not seen:
        raise InvalidInputError(f"empty {what}: nothing to import")


def _unpacked(chunks: Iterable[bytes], what: str, max_bytes: int | None) -> Iterator[bytes]:
    """The bytes, gunzipped when they start as gzip does."""
    rest = iter(chunks)
    head = b""
    for chunk in rest:
        head += chunk
        if len(head) >= len(GZIP_MAGIC):
            break
    stream = itertools.chain([head], rest)
    if head.startswith(GZIP_MAGIC):
        yield from _gunzip(stream, what, max_bytes)
    else:
        yield from stream


def _gunzip(chunks: Iterable[bytes], what: str, max_bytes: int | None) -> Iterator[bytes]:
    """Every gzip member in `chunks`, unpacked; corrupt or truncated streams are errors."""
    inflater = zlib.decompressobj(_GZIP_WBITS)
    fed = produced = 0
    for chunk in chunks:
        fed += len(chunk)
        data = chunk
        while data:
            budget = 0 if max_bytes is None else max_bytes - produced + 1  # 0: no limit
            try:
                out = inflater.decompress(data, budget)
            except zlib.error as exc:
                raise InvalidInputError(
                    f"not valid gzip within the first {fed} bytes: {exc}"
                ) from None
            produced += len(out)
            if max_bytes is not None and produced > max_bytes:
                raise PayloadTooLargeError(
                    f"the unpacked {what} is larger than max_body_bytes={max_bytes}"
                )
            yield out
            data = inflater.unconsumed_tail
            if inflater.eof:  # the member ended: another one may follow (as `cat a.gz b.gz`)
                data = inflater.unused_data
                if data and not data.startswith(GZIP_MAGIC[: len(data)]):
                    raise InvalidInputError(
                        f"not valid gzip: data after the gzip stream ends "
                        f"(byte {fed - len(data) + 1})"
                    )
                if data:
                    inflater = zlib.decompressobj(_GZIP_WBITS)
    if not inflater.eof:
        raise InvalidInputError(f"gzip stream truncated after {fed} bytes")
    yield inflater.flush()


def _split(chunks: Iterable[bytes]) -> Iterator[bytes]:
    """Lines (without their `\\n`) of a byte stream cut anywhere."""
    pending = b""
    for chunk in chunks:
        if b"\n" not in chunk:
            pending += chunk
            continue
        first, *middle, last = chunk.split(b"\n")
        yield pending + first
        yield from middle
        pending = last
    if pending:
        yield pending

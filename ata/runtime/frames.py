"""Length-prefixed frames between the host and a sandboxed decision process, with deadlines.

Two directions, two formats. Host -> child: a pickle (the host is trusted, and the child has to
rebuild the mission's settings dataclasses and the observation tables). Child -> host: never a
pickle, since unpickling runs code the sender chooses; a *safe frame* instead, a small JSON
header and raw numeric arrays whose dtype (from a fixed list), shape and length the host checks
before it makes an array of the bytes; each array starts at a multiple of 8 bytes (the header
and the arrays are padded), so the host's arrays are views of the frame it read, not copies.

Every frame on the pipe is an 8-byte little-endian length and that many bytes. The host reads
and writes with a deadline (`HostPipe`): a child that stops answering, or stops reading, costs
at most the time limit.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import pickle
import select
import struct
import time
from typing import Any

import numpy as np

MAX_FRAME = 1 << 31
"""The largest frame either side accepts (2 GiB): a length above it is a broken or hostile
peer, not data."""
SAFE_DTYPES = frozenset({"|b1", "|i1", "<i2", "<i4", "<i8", "|u1", "<u2", "<u4", "<u8", "<f4",
                         "<f8"})
"""The array dtypes a safe frame may carry: booleans, integers and floats, little-endian. Checked
as strings before numpy parses one, so no object or structured dtype is ever made."""
MAX_HEADER = 1 << 20
MAX_DEPTH = 16
"""How deep a safe frame's JSON header may nest: its answers are flat (a list of ranges is the
deepest, three levels); deeper is a broken or hostile peer."""
HEADER_ONLY = MAX_HEADER + 8
"""The longest answer that carries a header alone (a resolve, a probe, a start, trained_on)."""
PER_SCENARIO = 1 << 20
"""The bytes an answer may take per scenario of its batch (`answer_limit`)."""
_LEN = struct.Struct("<Q")
_HEAD = struct.Struct("<I")


class FrameError(Exception):
    """A frame that breaks the format: the peer is broken or hostile."""


class PeerTimeout(Exception):
    """The peer did not answer (or read) within the deadline."""


class PeerGone(Exception):
    """The peer closed its end (it exited or was killed)."""


# -- safe frames (child -> host) ------------------------------------------------------------------
def encode_safe(header: dict[str, Any], arrays: dict[str, np.ndarray] | None = None) -> bytes:
    """A safe frame's payload: the JSON header (with the arrays' layout added) and the arrays'
    bytes, in order."""
    layout, blobs = [], []
    for name, value in (arrays or {}).items():
        arr = np.ascontiguousarray(value)
        if arr.dtype.str not in SAFE_DTYPES:
            raise FrameError(f"array {name!r} has dtype {arr.dtype}, which a safe frame cannot "
                             "carry (booleans, integers and floats only)")
        layout.append([str(name), arr.dtype.str, [int(n) for n in arr.shape], int(arr.nbytes)])
        blobs.append(arr.tobytes() + b"\0" * (-arr.nbytes % 8))    # the next one aligned
    head = json.dumps({**header, "arrays": layout}).encode("utf-8")
    head += b" " * (-(_HEAD.size + len(head)) % 8)      # the first array starts aligned
    return _HEAD.pack(len(head)) + head + b"".join(blobs)


def answer_limit(batch: int) -> int:
    """The largest answer a decision call of a batch of `batch` scenarios may send: every array
    of an answer is per scenario (allocations, masks, reconstructions, results columns), so a
    bound per scenario and a header bounds it, whatever the method."""
    return MAX_HEADER + _HEAD.size + PER_SCENARIO * max(int(batch), 1)


def _depth(value: Any) -> int:
    """How deep a parsed JSON value nests (a scalar 0)."""
    if isinstance(value, dict):
        return 1 + max((_depth(v) for v in value.values()), default=0)
    if isinstance(value, list):
        return 1 + max((_depth(v) for v in value), default=0)
    return 0


def decode_safe(payload: bytes | bytearray) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The header and the arrays of a safe frame; a FrameError for anything out of format. Only
    JSON is parsed and only numeric arrays are made: nothing in the payload can run code. The
    arrays are views of `payload` (one copy of an answer: the frame read)."""
    if len(payload) < _HEAD.size:
        raise FrameError("a frame shorter than its header length")
    (n,) = _HEAD.unpack_from(payload)
    if n > MAX_HEADER or _HEAD.size + n > len(payload):
        raise FrameError(f"a header length of {n} bytes does not fit the frame")
    try:
        header = json.loads(bytes(payload[_HEAD.size:_HEAD.size + n]).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise FrameError(f"a header that is not JSON: {exc}") from None
    except RecursionError:
        raise FrameError("a header nested too deep to read") from None
    if not isinstance(header, dict) or not isinstance(header.get("arrays", []), list):
        raise FrameError("a header that is not a JSON object with an array list")
    if _depth(header) > MAX_DEPTH:
        raise FrameError(f"a header nested deeper than {MAX_DEPTH} levels")
    arrays: dict[str, np.ndarray] = {}
    offset = _HEAD.size + n
    for item in header.pop("arrays", []):
        if not (isinstance(item, list) and len(item) == 4 and isinstance(item[0], str)
                and item[1] in SAFE_DTYPES and isinstance(item[2], list)
                and all(isinstance(d, int) and not isinstance(d, bool) and 0 <= d < 2**40
                        for d in item[2]) and isinstance(item[3], int)):
            raise FrameError(f"an array entry out of format: {str(item)[:200]}")
        name, dtype, shape, nbytes = item
        dt = np.dtype(dtype)
        # exact integers (no int64 wrap-around), and numpy's own limit on dimensions
        if len(shape) > 32 or math.prod(shape) * dt.itemsize != nbytes \
                or offset + nbytes > len(payload):
            raise FrameError(f"array {name!r}: {nbytes} bytes do not make shape {shape} of "
                             f"{dtype}, or run past the frame")
        view = np.frombuffer(payload, dtype=dt, count=nbytes // dt.itemsize,
                                 offset=offset).reshape(shape)
        arrays[name] = view if view.flags.aligned else view.copy()
        offset += nbytes + (-nbytes % 8)
    if offset != len(payload):
        raise FrameError("bytes left over after the last array")
    return header, arrays


def grow_pipe(fd: int, size: int = 1 << 20) -> None:
    """Make a pipe's buffer `size` bytes where Linux allows (F_SETPIPE_SZ): an observation of a
    batch of 100 is some 350 kB, and a 64 kB pipe would cut each frame into a handful of
    writes and wake-ups on each side."""
    try:
        fcntl.fcntl(fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), size)
    except OSError:          # above /proc/sys/fs/pipe-max-size, or not Linux: the default
        pass


# -- the host's end: non-blocking, with deadlines -------------------------------------------------
class HostPipe:
    """The host's end of the child's pipes: `send` a pickled request, `recv` a safe frame, each
    before a deadline (a `time.monotonic()` value)."""

    def __init__(self, to_child: int, from_child: int):
        self.wfd, self.rfd = to_child, from_child
        for fd in (self.wfd, self.rfd):
            os.set_blocking(fd, False)
            grow_pipe(fd)

    def send(self, obj: Any, deadline: float) -> None:
        body = pickle.dumps(obj, protocol=5)
        data = memoryview(_LEN.pack(len(body)) + body)
        while data:
            self._wait(self.wfd, deadline, write=True)
            try:
                n = os.write(self.wfd, data)
            except BlockingIOError:
                continue
            except (BrokenPipeError, ConnectionResetError):
                raise PeerGone("the decision process closed its input") from None
            data = data[n:]

    def recv(self, deadline: float, limit: int = MAX_FRAME
             ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The next safe frame, refused (a FrameError) before it is read when it is longer than
        `limit` bytes (the call's `answer_limit`)."""
        (n,) = _LEN.unpack(self._read(_LEN.size, deadline))
        limit = min(limit, MAX_FRAME)
        if n > limit:
            raise FrameError(f"an answer of {n} bytes, over the limit of {limit} for this call")
        return decode_safe(self._read(n, deadline))

    def _read(self, n: int, deadline: float) -> bytearray:
        """`n` bytes, read into one buffer."""
        out = bytearray(n)
        view, got = memoryview(out), 0
        while got < n:
            self._wait(self.rfd, deadline, write=False)
            try:
                k = os.readv(self.rfd, [view[got:got + min(n - got, 1 << 22)]])
            except BlockingIOError:
                continue
            if not k:
                raise PeerGone("the decision process closed its output")
            got += k
        return out

    @staticmethod
    def _wait(fd: int, deadline: float, write: bool) -> None:
        left = deadline - time.monotonic()
        if left <= 0:
            raise PeerTimeout()
        r, w, _ = select.select([] if write else [fd], [fd] if write else [], [], left)
        if not (r or w):
            raise PeerTimeout()

    def close(self) -> None:
        for fd in (self.wfd, self.rfd):
            try:
                os.close(fd)
            except OSError:
                pass


# -- the child's end: blocking ---------------------------------------------------------------------
def child_recv(fd: int) -> Any | None:
    """The next request (unpickled: it comes from the host), or None at the end of input."""
    head = _read_exact(fd, _LEN.size)
    if head is None:
        return None
    (n,) = _LEN.unpack(head)
    body = _read_exact(fd, n)
    if body is None:
        return None
    return pickle.loads(body)


def child_send(fd: int, header: dict[str, Any], arrays: dict[str, np.ndarray] | None = None
               ) -> None:
    body = encode_safe(header, arrays)
    data = memoryview(_LEN.pack(len(body)) + body)
    while data:
        data = data[os.write(fd, data):]


def _read_exact(fd: int, n: int) -> bytes | None:
    out = bytearray()
    while len(out) < n:
        chunk = os.read(fd, min(n - len(out), 1 << 22))
        if not chunk:
            return None
        out += chunk
    return bytes(out)

"""The messages between the grader and its sandboxed processes: npz archives behind a length, read strictly.

A message is a dict. Its structure goes as JSON (member ``__json__.npy``, UTF-8 bytes) and its
numeric arrays and numpy scalars as ``.npy`` members of an uncompressed zip: an npz archive that
``np.load`` reads too. Never pickle: only numeric dtypes cross, in either direction.

The grader reads what a hostile process wrote, so ``unpack`` trusts nothing: the whole message is
at most ``MAX_MESSAGE_BYTES``; the zip is parsed here (not by ``zipfile``, not by ``np.load``) and
every member must be *stored* (a compressed member is refused, so nothing is ever inflated), named
as this module names them, and lie inside the message; each ``.npy`` header is parsed here too and
its dtype, shape and size must match the bytes that follow exactly before an array is made. Any
breach raises ``MessageError`` (a ValueError). What a message *says* (its fields) is checked by
the reader that expects it (``broker.py``).

Standard library and numpy only: this file also runs inside the sandbox (its folder is copied into
every kit).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import struct
import zipfile
import zlib

import numpy as np

MAX_MESSAGE_BYTES = 8 * 1024 * 1024  # one message, whole
MAX_MEMBERS = 2_000  # arrays in one message
MAX_ARRAY_ELEMENTS = 1_000_000  # numbers in one array
MAX_DEPTH = 32  # nesting of lists and dicts
MAX_TEXT = 300  # characters kept of an error message or a warning
_DTYPES = {np.dtype(name).str for name in ("<f8", "<f4", "<f2", "<i8", "<i4", "<i2", "i1", "<u8", "<u4", "<u2", "u1", "?")}
_MEMBER = re.compile(rb"^(__json__|a[0-9]{1,5})\.npy$")
_HEADER = re.compile(rb"^\{'descr': '(?P<descr>[<>|=][A-Za-z][0-9]{0,3})', 'fortran_order': (?P<fortran>True|False), "
                     rb"'shape': \((?P<shape>[0-9, ]{0,120})\), \} *\n$")
_MARKERS = ("__array__", "__scalar__")


class MessageError(ValueError):
    """A message that is not one this module writes: refused as a whole."""


class ChannelTimeout(Exception):
    """A write that did not end by its deadline: the other side stopped reading (or the run's time
    was up). The message says which limit, in the grader's words."""


# --------------------------------------------------------------------------------------------
# Structure <-> JSON + arrays
# --------------------------------------------------------------------------------------------


def encode(value, arrays, depth=0):
    """``value`` as JSON-able data; numpy arrays and scalars go into ``arrays`` as npz members.
    numpy scalars stay scalars on the other side (``np.int64(3)`` is not a 0-d array there)."""
    if depth > MAX_DEPTH:
        raise TypeError("a message nested too deeply")
    if isinstance(value, dict):
        if any(not isinstance(key, str) or key in _MARKERS for key in value):
            raise TypeError("message keys must be plain strings")
        return {key: encode(item, arrays, depth + 1) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [encode(item, arrays, depth + 1) for item in value]
    if isinstance(value, (np.ndarray, np.generic)):
        array = np.asarray(value)
        if array.dtype.kind not in "biuf":
            raise TypeError(f"only numeric arrays cross between grader and worker, got dtype {array.dtype}")
        name = f"a{len(arrays)}"
        arrays[name] = array
        return {"__scalar__" if isinstance(value, np.generic) else "__array__": name}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot send a {type(value).__name__}")


def decode(value, arrays, depth=0):
    if depth > MAX_DEPTH:
        raise MessageError("a message nested too deeply")
    if isinstance(value, dict):
        if len(value) == 1 and next(iter(value)) in _MARKERS:
            kind, name = next(iter(value.items()))
            if not isinstance(name, str) or name not in arrays:
                raise MessageError("a reference to an array the message does not hold")
            array = arrays[name]
            if kind == "__scalar__":
                if array.shape != ():
                    raise MessageError("a scalar that is not 0-d")
                return array[()]
            return array
        return {key: decode(item, arrays, depth + 1) for key, item in value.items()}
    if isinstance(value, list):
        return [decode(item, arrays, depth + 1) for item in value]
    return value


# --------------------------------------------------------------------------------------------
# The archive: written and read by hand (stored members only)
# --------------------------------------------------------------------------------------------


def _npy(array):
    """The .npy bytes of a numeric array (format 1.0, as numpy writes it)."""
    array = np.asarray(array)
    fortran = array.flags.f_contiguous and not array.flags.c_contiguous
    shape = repr(tuple(int(size) for size in array.shape))
    header = f"{{'descr': '{array.dtype.str}', 'fortran_order': {fortran}, 'shape': {shape}, }}"
    header = header.ljust(64 * ((len(header) + 11) // 64 + 1) - 11) + "\n"
    data = (array.T if fortran else np.ascontiguousarray(array)).tobytes()
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode("latin-1") + data


def pack(message):
    """The bytes of ``message``: an npz archive (stored members, no time stamps)."""
    arrays = {}
    meta = json.dumps(encode(message, arrays), separators=(",", ":"), allow_nan=True).encode()
    members = [(b"__json__.npy", _npy(np.frombuffer(meta, dtype=np.uint8)))]
    members += [(f"{name}.npy".encode(), _npy(array)) for name, array in arrays.items()]
    local, central = [], []
    offset = 0
    for name, data in members:
        crc = zlib.crc32(data)
        fields = (20, 0, 0, 0, 33, crc, len(data), len(data), len(name))
        local.append(b"PK\x03\x04" + struct.pack("<HHHHHIIIHH", *fields, 0) + name + data)
        central.append(b"PK\x01\x02" + struct.pack("<HHHHHHIIIHHHHHII", 20, *fields, 0, 0, 0, 0, 0, offset) + name)
        offset += len(local[-1])
    directory = b"".join(central)
    end = b"PK\x05\x06" + struct.pack("<HHHHIIH", 0, 0, len(members), len(members), len(directory), offset, 0)
    return b"".join(local) + directory + end


def _members(data):
    """{member name: its bytes} of an uncompressed zip, read from its central directory by hand."""
    if len(data) < 22 or data[-22:-18] != b"PK\x05\x06":
        raise MessageError("not an npz archive this grader writes (no end record where it belongs)")
    disk, cd_disk, here, total, cd_size, cd_offset, comment = struct.unpack("<HHHHIIH", data[-18:])
    if disk or cd_disk or here != total or comment or total > MAX_MEMBERS + 1 or cd_offset + cd_size != len(data) - 22:
        raise MessageError("an npz archive with a central directory this grader does not write")
    members, position = {}, cd_offset
    for _ in range(total):
        entry = data[position:position + 46]
        if len(entry) < 46 or entry[:4] != b"PK\x01\x02":
            raise MessageError("a broken central directory")
        fields = struct.unpack("<4sHHHHHHIIIHHHHHII", entry)
        flags, method, stored, size, name_length, extra_length, comment_length, offset = \
            fields[3], fields[4], fields[8], fields[9], fields[10], fields[11], fields[12], fields[16]
        name = data[position + 46:position + 46 + name_length]
        position += 46 + name_length + extra_length + comment_length
        if method != zipfile.ZIP_STORED or flags & 0x0009 or size != stored:
            raise MessageError("a compressed or encrypted member (only stored members are read)")
        if not _MEMBER.match(name) or name in members:
            raise MessageError("a member this grader does not write")
        header = data[offset:offset + 30]
        if len(header) < 30 or header[:4] != b"PK\x03\x04" or struct.unpack("<H", header[8:10])[0] != 0:
            raise MessageError("a member without its local header")
        start = offset + 30 + sum(struct.unpack("<HH", header[26:30]))
        if start + size > cd_offset:
            raise MessageError("a member that does not fit in the archive")
        members[name] = data[start:start + size]
    if position != cd_offset + cd_size:
        raise MessageError("a central directory of the wrong size")
    return members


def _array(raw):
    """One ``.npy`` member as an array: header parsed here; dtype, shape and size must fit the bytes."""
    if raw[:6] != b"\x93NUMPY" or len(raw) < 10 or raw[6] not in (1, 2, 3):
        raise MessageError("a member that is not an .npy array")
    if raw[6] == 1:
        length, start = struct.unpack("<H", raw[8:10])[0], 10
    else:
        length, start = struct.unpack("<I", raw[8:12])[0], 12
    if length > 4096 or start + length > len(raw):
        raise MessageError("an .npy header too long")
    header = _HEADER.match(raw[start:start + length])
    if header is None:
        raise MessageError("an .npy header this grader does not write")
    descr, fortran = header["descr"].decode(), header["fortran"] == b"True"
    sizes = [part.strip() for part in header["shape"].split(b",")]
    if sizes and sizes[-1] == b"":
        sizes.pop()
    if descr not in _DTYPES or len(sizes) > 8 or not all(size.isdigit() and len(size) <= 7 for size in sizes):
        raise MessageError("an array of a dtype or shape that is not accepted (numbers only)")
    shape = tuple(int(size) for size in sizes)
    count = 1
    for size in shape:
        count *= size
    dtype = np.dtype(descr)
    if count > MAX_ARRAY_ELEMENTS or len(raw) - start - length != count * dtype.itemsize:
        raise MessageError("an array whose size does not match its bytes")
    flat = np.frombuffer(raw, dtype=dtype, count=count, offset=start + length)
    return flat.reshape(shape, order="F" if fortran else "C").copy()


def unpack(data):
    """The message in ``data``, read without trusting it (see the module docstring)."""
    if len(data) > MAX_MESSAGE_BYTES:
        raise MessageError("a message larger than the grader accepts")
    members = _members(bytes(data))
    if b"__json__.npy" not in members:
        raise MessageError("an archive without its structure")
    meta = _array(members.pop(b"__json__.npy"))
    if meta.dtype != np.uint8 or meta.ndim != 1:
        raise MessageError("a structure that is not UTF-8 bytes")
    try:
        structure = json.loads(meta.tobytes().decode("utf-8"))
    except (ValueError, RecursionError):
        raise MessageError("a structure that is not JSON") from None
    arrays = {name[:-4].decode(): _array(raw) for name, raw in members.items()}
    return decode(structure, arrays)


def fingerprint(message):
    """A digest of ``message`` that depends only on its content."""
    arrays = {}
    meta = encode(message, arrays)
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True).encode())
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


# --------------------------------------------------------------------------------------------
# Framing: an 8-byte big-endian length, then the archive
# --------------------------------------------------------------------------------------------


def write_message(fd, message):
    """Write ``message`` on ``fd`` (blocking; the grader's side writes from a thread of its own and
    waits for it with a deadline: ``hwtools.grade.processes``)."""
    data = pack(message)
    view = memoryview(struct.pack(">Q", len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def read_exactly(fd, count):
    chunks, remaining = [], count
    while remaining:
        chunk = os.read(fd, min(remaining, 1 << 20))
        if not chunk:
            raise EOFError("the other side closed the channel")
        chunks.append(chunk)
        remaining -= len(chunk)
    return b"".join(chunks)


def read_message(fd):
    """The next message on ``fd`` (blocking): for the sandboxed side, which reads the grader."""
    (length,) = struct.unpack(">Q", read_exactly(fd, 8))
    if length > MAX_MESSAGE_BYTES:
        raise MessageError("a message larger than accepted")
    return unpack(read_exactly(fd, length))


def text(value):
    """``value`` as one line of printable text of at most MAX_TEXT characters (the grader's cut)."""
    line = " ".join("".join(ch if ch.isprintable() else " " for ch in str(value)).split())
    return line if len(line) <= MAX_TEXT else line[:MAX_TEXT - 3] + "..."

"""Reading one submission without trusting it: a folder or a zip in, a private copy of its
``hwlib/**/*.py`` and notebooks out (``open_submission``), or ``Unusable`` with the reason.

A submission's ``hwlib/`` may sit at the top or up to ``KIT_DEPTH`` folders down; a submission of
the bare library files is read as ``hwlib/``, and a folder whose only content is one ``.zip`` is
read as that zip. Only ``hwlib/**/*.py`` and the notebooks are copied, into a private temporary
folder, and only after every check passed: a zip entry with an absolute path or a ``..`` part, a
link, a file over its size limit (the declared sizes are checked before any byte is extracted, and
the bytes are counted while extracting), too many files, or a file name with control characters
reject the whole submission with the reason, and so do two files that are one file on macOS or
Windows (names that differ only in letter case or Unicode normalisation: ``markers.name_clash``). A zip's entries are counted in its central directory
itself, record by record, before anything parses it: a zip whose end record under-declares its
entries is refused after ``MAX_ENTRIES`` records, with bounded memory.
"""

from __future__ import annotations

import hashlib
import os
import re
import stat
import struct
import tempfile
import zipfile
import zlib
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from hwtools import markers
from hwtools.grade import blocks, kits
from hwtools.grade.safe_text import printable

MB = 1_000_000
MAX_PY_BYTES = blocks.MAX_FILE_BYTES  # per Python file: what the grader reads of one file
MAX_NOTEBOOK_BYTES = 20 * MB  # per notebook (outputs with figures included)
MAX_SUBMISSION_BYTES = 50 * MB  # all the files taken from one submission together
MAX_FILES = 400  # files taken from one submission
MAX_ENTRIES = 100_000  # entries of one zip, or files and folders looked at in one submission folder
KIT_DEPTH = 2  # hwlib/ may sit this many folders below the top of a submission
NOTEBOOKS = "notebooks"
EMPTY = "empty"  # the status of a submission with nothing in it


class Unusable(Exception):
    """A submission that is not graded: ``status`` is empty, unreadable or rejected; ``reason`` says why."""

    def __init__(self, status, reason=""):
        reason = printable(reason)  # it may quote names the submission chose
        super().__init__(f"{status}: {reason}" if reason else status)
        self.status, self.reason = status, reason

    @property
    def text(self):
        return f"{self.status}: {self.reason}" if self.reason else self.status


def size_text(count):
    """``count`` bytes in words: MB from a million on."""
    return f"{count / MB:g} MB" if count >= MB else f"{count} bytes"


@dataclass(frozen=True)
class _Entry:
    path: str  # relative POSIX path inside the submission
    kind: str  # file, dir, link or other
    size: int  # declared size (zip) or the size lstat gives (folder)
    handle: object = None  # ZipInfo, or the absolute path of a file


def _junk(parts):
    """Never looked into: what editors, Jupyter, Python, macOS and version control leave (``markers.is_leftover``)."""
    return markers.is_leftover("/".join(parts))


CENTRAL_RECORD = b"PK\x01\x02"
CENTRAL_RECORD_BYTES = 46  # a central directory record before its name, extra field and comment


def _central_directory(handle):
    """(offset, length) of a zip's central directory, from its end record (zip64 included); the
    offset is where the directory really is, just before the end record, as zipfile finds it."""
    handle.seek(0, os.SEEK_END)
    size = handle.tell()
    tail_start = max(0, size - 65_536 - 22)
    handle.seek(tail_start)
    tail = handle.read()
    end = tail.rfind(b"PK\x05\x06")
    if end < 0 or len(tail) < end + 22:
        raise Unusable("unreadable", "not a zip file (no end-of-archive record)")
    length, = struct.unpack_from("<I", tail, end + 12)
    record_at = tail_start + end
    locator = end - 20
    if locator >= 0 and tail[locator:locator + 4] == b"PK\x06\x07":
        offset, = struct.unpack_from("<Q", tail, locator + 8)
        handle.seek(offset)
        record = handle.read(56)
        if record[:4] == b"PK\x06\x06" and len(record) == 56:
            length, = struct.unpack_from("<Q", record, 40)
            record_at = offset
    return max(0, record_at - length), min(length, size)


def _zip_entry_count(path, limit):
    """The entries of the zip at ``path`` counted in its central directory itself, record by
    record (whatever its end record declares), reading at most a MiB at a time; stops past ``limit``."""
    with open(path, "rb") as handle:
        offset, left = _central_directory(handle)
        handle.seek(offset)
        buffer, at, count = b"", 0, 0
        while True:
            if len(buffer) - at < CENTRAL_RECORD_BYTES and left > 0:
                chunk = handle.read(min(1 << 20, left))
                left -= len(chunk)
                buffer, at = buffer[at:] + chunk, 0
            if len(buffer) - at < CENTRAL_RECORD_BYTES or not buffer.startswith(CENTRAL_RECORD, at):
                return count
            names, extra, comment = struct.unpack_from("<HHH", buffer, at + 28)
            count += 1
            if count > limit:
                return count
            skip = CENTRAL_RECORD_BYTES + names + extra + comment
            if skip <= len(buffer) - at:
                at += skip
                continue
            skip -= len(buffer) - at  # the record goes on past the buffer
            handle.seek(skip, os.SEEK_CUR)
            left -= skip
            buffer, at = b"", 0


def _zip_entries(archive):
    entries, seen = [], set()
    for info in archive.infolist():
        name = info.filename.replace("\\", "/")
        parts = [part for part in name.split("/") if part not in ("", ".")]
        if name.startswith("/") or re.match(r"^[A-Za-z]:", name) or ".." in parts:
            raise Unusable("rejected", f"a path that leaves the submission in the zip: {info.filename!r}")
        if not parts:
            continue
        file_type = stat.S_IFMT(info.external_attr >> 16)  # 0 where the zip tool recorded none
        if file_type == stat.S_IFLNK:
            kind = "link"
        elif info.is_dir() or file_type == stat.S_IFDIR:
            kind = "dir"
        elif file_type not in (0, stat.S_IFREG):
            kind = "other"
        else:
            kind = "file"
        path = "/".join(parts)
        if kind != "dir":
            if path in seen:
                raise Unusable("rejected", f"{path} appears twice in the zip")
            seen.add(path)
        entries.append(_Entry(path, kind, info.file_size, info))
    return entries


def _folder_entries(root):
    """Entries of a submission folder: everything down to the depth where a kit may sit, and the
    whole of every ``hwlib``/``notebooks`` folder; links are listed, never followed."""
    entries, pending = [], [(Path(root), ())]
    while pending:
        folder, parts = pending.pop()
        try:
            with os.scandir(folder) as scan:
                items = sorted(scan, key=lambda item: item.name)
        except OSError as error:
            raise Unusable("unreadable", f"{'/'.join(parts) or 'the submission'}: {error.strerror}") from None
        for item in items:
            path = parts + (item.name,)
            if _junk(path[-1:]):
                continue
            if len(entries) >= MAX_ENTRIES:
                raise Unusable("rejected", f"more than {MAX_ENTRIES} files and folders")
            info = item.stat(follow_symlinks=False)
            if stat.S_ISLNK(info.st_mode):
                entries.append(_Entry("/".join(path), "link", 0))
            elif stat.S_ISDIR(info.st_mode):
                entries.append(_Entry("/".join(path), "dir", 0))
                inside_kit = any(part in (blocks.PACKAGE, NOTEBOOKS) for part in path)
                if len(path) <= KIT_DEPTH + 1 or inside_kit:
                    pending.append((Path(item.path), path))
            elif stat.S_ISREG(info.st_mode):
                entries.append(_Entry("/".join(path), "file", info.st_size, item.path))
            else:
                entries.append(_Entry("/".join(path), "other", 0))
    return entries


def _find_kit(entries, kit_names):
    """(prefix of the kit root, {entry path: path in the kit}) of the files to take, or raise."""
    files = [entry for entry in entries if entry.kind != "dir"]
    clash = markers.name_clash(entry.path for entry in files)
    if clash:
        raise Unusable("rejected", f"{clash[0]} and {clash[1]} are one file on macOS and Windows (their names differ "
                                   "only in letter case or Unicode normalisation); rename one and send again")
    roots = set()
    for entry in files:
        parts = entry.path.split("/")
        for depth in range(min(len(parts) - 1, KIT_DEPTH + 1)):
            if parts[depth] == blocks.PACKAGE and entry.path.endswith(".py"):
                roots.add("/".join(parts[:depth]))
    flat = False
    if not roots:  # the library's files without their hwlib/ folder
        for entry in files:
            parts = entry.path.split("/")
            if len(parts) <= KIT_DEPTH + 1 and parts[-1] in kit_names:
                roots.add("/".join(parts[:-1]))
        flat = bool(roots)
    if not roots:
        return None
    shallowest = min(len(root.split("/")) if root else 0 for root in roots)
    roots = sorted(root for root in roots if (len(root.split("/")) if root else 0) == shallowest)
    if len(roots) > 1:
        where = ", ".join(f"{root}/" for root in roots[:4])
        raise Unusable("unreadable", f"more than one copy of the kit ({where}); send one")
    root = roots[0]
    prefix = f"{root}/" if root else ""
    taken = {}
    for entry in entries:
        if not entry.path.startswith(prefix):
            continue
        inner = entry.path[len(prefix):].split("/")
        if flat:
            wanted = len(inner) == 1 and inner[0] in kit_names
            target = f"{blocks.PACKAGE}/{inner[0]}"
        elif inner[0] == blocks.PACKAGE:
            wanted = len(inner) > 1 and (entry.kind in ("link", "other") or inner[-1].endswith(".py"))
            target = "/".join(inner)
        else:
            notebook = inner[-1].endswith(".ipynb") and (len(inner) == 1 or (len(inner) == 2 and inner[0] == NOTEBOOKS))
            wanted, target = notebook, "/".join(inner)
        if not wanted or entry.kind == "dir":
            continue
        if entry.kind == "link":
            raise Unusable("rejected", f"{entry.path} is a link; only plain files are read")
        if entry.kind != "file":
            raise Unusable("rejected", f"{entry.path} is not a regular file")
        if any(ord(char) < 32 or char == "\x7f" for char in entry.path):
            raise Unusable("rejected", f"a file name with control characters: {entry.path!r}")
        taken[entry.path] = target
    return root, flat, taken


def _check_sizes(entries, taken):
    by_path = {entry.path: entry for entry in entries}
    if len(taken) > MAX_FILES:
        raise Unusable("rejected", f"{len(taken)} files in hwlib/ and the notebooks, more than the {MAX_FILES} read")
    total = 0
    for path in sorted(taken):
        entry = by_path[path]
        limit = MAX_NOTEBOOK_BYTES if path.endswith(".ipynb") else MAX_PY_BYTES
        if entry.size > limit:
            raise Unusable("rejected", f"{path}: {size_text(entry.size)}, more than the {size_text(limit)} read per file")
        total += entry.size
    if total > MAX_SUBMISSION_BYTES:
        raise Unusable("rejected", f"{size_text(total)} of code and notebooks, more than the {size_text(MAX_SUBMISSION_BYTES)} "
                                   "read per submission")


def _copy_counted(source, target, path, declared, limit):
    """Copy the stream ``source`` to the file ``target``, never more than ``limit`` bytes nor more
    than ``declared``; returns the bytes."""
    data = bytearray()
    while True:
        chunk = source.read(65_536)
        if not chunk:
            break
        data += chunk
        if len(data) > declared:
            raise Unusable("rejected", f"{path}: more bytes than the {size_text(declared)} its header declares")
        if len(data) > limit:
            raise Unusable("rejected", f"{path}: more than the {size_text(limit)} read per file")
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(bytes(data))
    return bytes(data)


@dataclass
class OpenedSubmission:
    """A submission copied, checked, into a private folder: ``kit`` (with ``hwlib/``), ``digest``
    (sha-256 of the files taken), ``notes`` (what the reader did that the student should know)."""

    kit: Path
    digest: str
    notes: list = field(default_factory=list)


def _extract(entries, taken, opener, kit, declared_sizes):
    """Copy the ``taken`` entries into ``kit``; the sha-256 of what was copied. ``declared_sizes``: an
    entry may not hold more bytes than its declared size (a zip's header)."""
    by_path = {entry.path: entry for entry in entries}
    digest = hashlib.sha256()
    for path in sorted(taken, key=lambda name: taken[name]):
        target = taken[path]
        entry = by_path[path]
        limit = MAX_NOTEBOOK_BYTES if path.endswith(".ipynb") else MAX_PY_BYTES
        with opener(entry) as stream:
            data = _copy_counted(stream, kit / target, path, entry.size if declared_sizes else limit, limit)
        digest.update(target.encode() + b"\0" + hashlib.sha256(data).digest())
    return digest.hexdigest()


def _zip_opener(archive):
    @contextmanager
    def opener(entry):
        with archive.open(entry.handle) as stream:
            yield stream
    return opener


@contextmanager
def _file_opener(entry):
    fd = os.open(entry.handle, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    with os.fdopen(fd, "rb") as stream:
        if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
            raise Unusable("rejected", f"{entry.path} is not a regular file")
        yield stream


def _read_zip(path, kit_names, kit):
    if os.path.getsize(path) == 0:
        raise Unusable(EMPTY)
    if _zip_entry_count(path, MAX_ENTRIES) > MAX_ENTRIES:
        raise Unusable("rejected", f"a zip of more than {MAX_ENTRIES} entries (counted in its central directory), "
                                   "more than are read")
    try:
        with zipfile.ZipFile(path) as archive:
            entries = [entry for entry in _zip_entries(archive) if not _junk(entry.path.split("/"))]
            if not any(entry.kind != "dir" for entry in entries):
                raise Unusable(EMPTY)
            found = _find_kit(entries, kit_names)
            if found is None:
                raise Unusable("unreadable", _no_kit_reason(entries))
            root, flat, taken = found
            for entry in entries:
                if entry.path in taken and entry.handle.flag_bits & 0x1:
                    raise Unusable("unreadable", f"{entry.path} is encrypted")
            _check_sizes(entries, taken)
            digest = _extract(entries, taken, _zip_opener(archive), kit, declared_sizes=True)
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, ValueError, OSError) as error:
        raise Unusable("unreadable", f"a damaged or unsupported zip ({error})") from None
    return digest, _kit_notes(root, flat)


def _read_folder(path, kit_names, kit, nested_zip=True):
    entries = _folder_entries(path)
    if not any(entry.kind != "dir" for entry in entries):
        raise Unusable(EMPTY)
    found = _find_kit(entries, kit_names)
    if found is None:
        zips = [entry for entry in entries if entry.kind == "file" and "/" not in entry.path
                and entry.path.lower().endswith(".zip")]
        if nested_zip and len(zips) == 1:
            digest, notes = _read_zip(zips[0].handle, kit_names, kit)
            return digest, [f"read from {zips[0].path}"] + notes
        raise Unusable("unreadable", _no_kit_reason(entries))
    root, flat, taken = found
    _check_sizes(entries, taken)
    try:
        digest = _extract(entries, taken, _file_opener, kit, declared_sizes=False)
    except OSError as error:
        raise Unusable("unreadable", f"{error.filename or 'a file'}: {error.strerror}") from None
    return digest, _kit_notes(root, flat)


def _no_kit_reason(entries):
    shown = sorted(entry.path for entry in entries if "/" not in entry.path)[:5]
    return (f"no {blocks.PACKAGE}/ folder with Python files at the top or up to {KIT_DEPTH} folders down "
            f"(found: {', '.join(shown) or 'nothing'})")


def _kit_notes(root, flat):
    notes = []
    if flat:
        notes.append(f"the library's files were found without their {blocks.PACKAGE}/ folder"
                     f"{f' (in {root}/)' if root else ''}; they were read as {blocks.PACKAGE}/")
    return notes


@contextmanager
def open_submission(path, kit_names=()):
    """Copy what the grader needs of the submission at ``path`` (a folder or a .zip) into a private
    temporary folder, after checking it; yields an ``OpenedSubmission``, or raises ``Unusable``.
    ``kit_names``: the file names of the kit's ``hwlib/`` (``finite_diff.py``, ...), by which a
    submission of the bare files is recognised. The folder is deleted on leaving."""
    path = Path(path)
    scratch = Path(tempfile.mkdtemp(prefix="hwclass-"))
    kit = scratch / "kit"
    kit.mkdir()
    try:
        info = os.lstat(path)
        if stat.S_ISLNK(info.st_mode):
            raise Unusable("rejected", "the submission is a link; only plain folders and files are read")
        if stat.S_ISDIR(info.st_mode):
            digest, notes = _read_folder(path, frozenset(kit_names), kit)
        elif stat.S_ISREG(info.st_mode) and path.suffix.lower() == ".zip":
            digest, notes = _read_zip(path, frozenset(kit_names), kit)
        else:
            raise Unusable("unreadable", "not a folder or a .zip file")
        yield OpenedSubmission(kit, digest, notes)
    finally:
        kits.remove_tree(scratch)


PLAIN_ID = re.compile(r"^[A-Za-z0-9@+_-][A-Za-z0-9._@+-]{0,99}$")  # kept as they are: no "~" or "%", 100 at most
NAME_HASH = 16  # hex digits of sha-256 in a long id's file name


def file_name(student):
    """The file name (without suffix) of ``student``'s feedback and saved state: bounded in length
    (at most 119 characters) and collision-free by construction. A plain id (letters, digits,
    ``._@+-``, not starting with a dot, at most 100 characters) is its own name; any other id is
    percent-encoded (UTF-8, every other character as %XX: one id, one encoding) behind a ``~``,
    which no plain id contains; an encoding longer than 100 characters is cut and followed by a
    second ``~`` and a hash of the exact id. So "Ana María" is ``~Ana%20Mar%C3%ADa`` and never the
    name of the plain id ``Ana_Mar_a-8358ed27``."""
    if PLAIN_ID.match(student):
        return student
    encoded = "".join(char if re.match(r"[A-Za-z0-9._@+-]", char) else
                      "".join(f"%{byte:02X}" for byte in char.encode("utf-8", "surrogatepass")) for char in student)
    if len(encoded) <= 100:
        return "~" + encoded
    return f"~{encoded[:100]}~{hashlib.sha256(student.encode('utf-8', 'surrogatepass')).hexdigest()[:NAME_HASH]}"


def kit_file_names(layout):
    """The names of the files directly in the reference's ``hwlib/`` that hold TODO blocks."""
    names = set()
    for relative in layout.blocks_by_file:
        parts = PurePosixPath(relative).parts
        if len(parts) == 2 and parts[0] == blocks.PACKAGE:
            names.add(parts[1])
    return frozenset(names)

"""Grade a class: a folder of submissions to one gradebook (CSV) and one Markdown feedback file per student.

    python -m hwtools.grade SUBMISSIONS_DIR --gradebook grades.csv --feedback FEEDBACK_DIR [--jobs N]

``SUBMISSIONS_DIR`` holds one folder or one ``.zip`` per student, named by the student's id
(``alice/``, ``bob.zip``). Each holds the student's ``hwlib/`` (and, if they sent them, the
notebooks), at the top or up to two folders down (``bob.zip`` holding ``bob/hwlib/...`` or
``hw1/hwlib/...``); a submission of the bare library files (``finite_diff.py``, ``logreg.py``, ...
without their ``hwlib/`` folder) is read as ``hwlib/``, and a folder whose only content is one
``.zip`` is read as that zip.

Nothing in a submission is trusted. Only ``hwlib/**/*.py`` and the notebooks are copied, into a
private temporary folder, and only after every check passed: a zip entry with an absolute path
or a ``..`` part, a link, a file over its size limit (the declared sizes are checked before any
byte is extracted, and the bytes are counted while extracting), or too many files reject the
whole submission with the reason. The student's code then runs only in the grader's sandbox.

Submissions are graded side by side (``--jobs``, default one per CPU), each in its own sandbox,
by ONE ``Grader``: the reference's answers are computed once for the class. Each student's
result is saved as it finishes (``.<gradebook name>-state/<student>.json`` next to the
gradebook, keyed by a hash of the submission's files and of everything that decides the
points: the reference, the hidden checks, the grader's code and its limits), so an
interrupted run resumes where it stopped, and a rerun grades only what changed (delete that
folder to grade everything again). The gradebook holds no time stamps: grading the same folder
twice writes the same bytes.

Time limits: the grader runs each TODO of a submission as one sandboxed run, and ``--time-limit``
bounds each run (wall clock and CPU). Code that never ends costs that limit once per TODO it hangs
in; that TODO gets 0, the others keep their points, and the status says ``timed out: <TODOs>``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import re
import shutil
import stat
import sys
import tempfile
import threading
import time
import zipfile
import zlib
from concurrent.futures import ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from hwtools.grade import blocks
from hwtools.grade.feedback import failure_words
from hwtools.grade.grader import HIDDEN_CHECKS, KIT_ROOT, Grader, GradingError, has_solutions
from hwtools.todos import AUTO_POINTS, TODOS

MB = 1_000_000
MAX_PY_BYTES = blocks.MAX_FILE_BYTES  # per Python file: what the grader reads of one file
MAX_NOTEBOOK_BYTES = 20 * MB  # per notebook (outputs with figures included)
MAX_SUBMISSION_BYTES = 50 * MB  # all the files taken from one submission together
MAX_FILES = 400  # files taken from one submission
MAX_ENTRIES = 100_000  # entries of one zip, or files and folders looked at in one submission folder
KIT_DEPTH = 2  # hwlib/ may sit this many folders below the top of a submission
# Never looked into: macOS resource forks, caches, virtual environments, version control.
JUNK_PARTS = {"__MACOSX", "__pycache__", ".git", ".venv", "venv", ".ipynb_checkpoints", "node_modules", ".DS_Store"}
NOTEBOOKS = "notebooks"
STATE_VERSION = 1
STOPPED_NOTE = "the run of your code stopped"  # how the grader's note on a stopped run begins
GRADED, NOT_ISOLATED, EMPTY = "graded", "not isolated", "empty"


def _umask():
    """The process's umask, read without changing it (Linux), else the usual 022."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


class Unusable(Exception):
    """A submission that is not graded: ``status`` is empty, unreadable or rejected; ``reason`` says why."""

    def __init__(self, status, reason=""):
        super().__init__(f"{status}: {reason}" if reason else status)
        self.status, self.reason = status, reason

    @property
    def text(self):
        return f"{self.status}: {self.reason}" if self.reason else self.status


def _size(count):
    return f"{count / MB:g} MB" if count >= MB else f"{count} bytes"


# --------------------------------------------------------------------------------------------
# Reading one submission without trusting it
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Entry:
    path: str  # relative POSIX path inside the submission
    kind: str  # file, dir, link or other
    size: int  # declared size (zip) or the size lstat gives (folder)
    handle: object = None  # ZipInfo, or the absolute path of a file


def _junk(parts):
    return any(part in JUNK_PARTS or part.startswith("._") for part in parts)


def _zip_entry_count(path):
    """The number of entries a zip's end record declares (zip64 included), read before the central
    directory is parsed, so that a zip of millions of entries is refused without reading them."""
    with open(path, "rb") as handle:
        handle.seek(0, os.SEEK_END)
        size = handle.tell()
        tail_start = max(0, size - 65_536 - 22)
        handle.seek(tail_start)
        tail = handle.read()
        end = tail.rfind(b"PK\x05\x06")
        if end < 0 or len(tail) < end + 22:
            raise Unusable("unreadable", "not a zip file (no end-of-archive record)")
        count = int.from_bytes(tail[end + 10:end + 12], "little")
        locator = end - 20
        if count == 0xFFFF and locator >= 0 and tail[locator:locator + 4] == b"PK\x06\x07":
            offset = int.from_bytes(tail[locator + 8:locator + 16], "little")
            handle.seek(offset)
            record = handle.read(56)
            if record[:4] == b"PK\x06\x06" and len(record) == 56:
                count = int.from_bytes(record[32:40], "little")
    return count


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
            raise Unusable("rejected", f"{path}: {_size(entry.size)}, more than the {_size(limit)} read per file")
        total += entry.size
    if total > MAX_SUBMISSION_BYTES:
        raise Unusable("rejected", f"{_size(total)} of code and notebooks, more than the {_size(MAX_SUBMISSION_BYTES)} "
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
            raise Unusable("rejected", f"{path}: more bytes than the {_size(declared)} its header declares")
        if len(data) > limit:
            raise Unusable("rejected", f"{path}: more than the {_size(limit)} read per file")
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
    count = _zip_entry_count(path)
    if count > MAX_ENTRIES:
        raise Unusable("rejected", f"a zip of {count} entries, more than the {MAX_ENTRIES} read")
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
        blocks.remove_tree(scratch)


def kit_file_names(layout):
    """The names of the files directly in the reference's ``hwlib/`` that hold TODO blocks."""
    names = set()
    for relative in layout.blocks_by_file:
        parts = PurePosixPath(relative).parts
        if len(parts) == 2 and parts[0] == blocks.PACKAGE:
            names.add(parts[1])
    return frozenset(names)


# --------------------------------------------------------------------------------------------
# The class: submissions, saved results, gradebook, feedback
# --------------------------------------------------------------------------------------------


def find_submissions(folder, skip=()):
    """{student id: [paths]} of the submissions in ``folder``: each folder and each file (a ``.zip``;
    anything else is listed too, to be reported as unreadable), by name without ``.zip``; names
    starting with a dot and the paths in ``skip`` (the gradebook, the feedback folder) are left out."""
    folder = Path(folder)
    skip = {os.path.realpath(path) for path in skip}
    found = {}
    for item in sorted(folder.iterdir(), key=lambda item: item.name):
        if item.name.startswith(".") or item.name == "__MACOSX" or os.path.realpath(item) in skip:
            continue
        student = item.name[:-4] if item.name.lower().endswith(".zip") and not item.is_dir() else item.name
        found.setdefault(student, []).append(item)
    return found


def grading_fingerprint(grader):
    """A hash of everything, besides the submission, that decides a result: the reference's
    ``hwlib``, its hidden checks, the grader's own code and the tables it reads, the limits, the
    Python and the sandbox. A saved result is reused only under the same fingerprint."""
    digest = hashlib.sha256(f"state {STATE_VERSION}\0".encode())
    digest.update(blocks.files_digest(grader.layout.files).encode())
    hidden = Path(grader.reference) / HIDDEN_CHECKS
    digest.update(hidden.read_bytes() if hidden.is_file() else b"no hidden checks")
    code = sorted(Path(__file__).resolve().parent.glob("*.py")) + [Path(__file__).resolve().parents[1] / "todos.py"]
    for path in code:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    box = grader.sandbox
    for part in (box.python, box.isolated, box.how, box.time_limit, box.memory_limit):
        digest.update(f"\0{part}".encode())
    return digest.hexdigest()


@dataclass
class StudentResult:
    """One student's row: ``status`` (graded, not isolated, timed out: ..., empty, unreadable: ...,
    rejected: ...), ``result`` (the grader's dict, or None when nothing was graded), ``notes``
    (what the reader did), ``reused`` (taken from the saved state)."""

    student: str
    status: str
    result: dict | None = None
    notes: list = field(default_factory=list)
    reused: bool = False
    seconds: float = 0.0

    @property
    def auto_total(self):
        return self.result["total"]["auto_earned"] if self.result else 0.0

    def auto_points(self, todo):
        if not self.result:
            return 0.0
        return next((entry["auto_earned"] for entry in self.result["todos"] if entry["id"] == todo), 0.0)


def status_of(result):
    """The gradebook's status of a graded result."""
    timed_out = [entry["id"] for entry in result["todos"] if entry["status"] == "time limit"]
    parts = [f"timed out: {', '.join(timed_out)}"] if timed_out else []
    if not result["isolated"]:
        parts.append(NOT_ISOLATED)
    return "; ".join(parts) or GRADED


class StateStore:
    """Saved results, one JSON file per student, written atomically as each one finishes."""

    def __init__(self, folder, fingerprint):
        self.folder = Path(folder)
        self.fingerprint = fingerprint

    def key(self, digest):
        return hashlib.sha256(f"{self.fingerprint}\0{digest}".encode()).hexdigest()

    def _path(self, student):
        return self.folder / f"{_safe_name(student)}.json"

    def load(self, student, digest):
        try:
            data = json.loads(self._path(student).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("key") != self.key(digest) or data.get("student") != student:
            return None
        return data

    def save(self, student, digest, status, result, notes):
        self.folder.mkdir(parents=True, exist_ok=True)
        data = {"version": STATE_VERSION, "student": student, "key": self.key(digest), "status": status,
                "notes": notes, "result": result}
        _write_atomically(self._path(student), json.dumps(data, indent=1, sort_keys=True) + "\n")


def _safe_name(student):
    """A file name for the student's files: the id itself where it is plain, else the id with the
    other characters replaced and a short hash of it (two ids never share a file)."""
    name = re.sub(r"[^A-Za-z0-9._@+-]", "_", student)
    if name == student and name.strip("."):
        return name
    return f"{name}-{hashlib.sha256(student.encode()).hexdigest()[:8]}"


def _write_atomically(path, text):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)
            os.fchmod(stream.fileno(), 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _public(result, student):
    """The result with the paths of this machine replaced by what a student may read."""
    result = dict(result)
    result["submission"] = student
    result["reference"] = "the instructor's reference solution"
    result.pop("seconds", None)
    return result


def grade_one(grader, path, student, kit_names, store=None):
    """Read and grade one submission; a ``StudentResult``. With ``store``, a saved result for the
    same files and grading is reused, and a new one is saved."""
    started = time.monotonic()
    paths = path if isinstance(path, list) else [path]
    if len(paths) > 1:
        names = ", ".join(item.name for item in paths)
        return StudentResult(student, f"rejected: more than one submission under this id ({names})")
    try:
        with open_submission(paths[0], kit_names) as opened:
            if store is not None:
                saved = store.load(student, opened.digest)
                if saved is not None:
                    return StudentResult(student, saved["status"], saved["result"], saved["notes"], reused=True)
            result = _public(grader.grade(opened.kit), student)
            status = status_of(result)
            if store is not None:
                store.save(student, opened.digest, status, result, opened.notes)
            return StudentResult(student, status, result, opened.notes, seconds=time.monotonic() - started)
    except Unusable as unusable:
        return StudentResult(student, unusable.text, seconds=time.monotonic() - started)


# ---- the gradebook ---------------------------------------------------------------------------


def _points(value):
    return f"{value:g}"


def gradebook_header():
    """The gradebook's columns: student, status, one per TODO's automatic points, the automatic
    total, one (empty) per TODO's points graded by hand, notes; maxima in the headers."""
    header = ["student", "status"]
    header += [f"{todo.id} {todo.title} (/{_points(todo.auto)})" for todo in TODOS if todo.auto]
    header.append(f"auto total (/{_points(AUTO_POINTS)})")
    header += [f"{todo.id} by hand: {todo.manual_what if todo.auto else todo.title} (/{_points(todo.manual)})"
               for todo in TODOS if todo.manual]
    header.append("notes")
    return header


def _cell(text):
    """A text cell a spreadsheet shows as text (no formula from a student's file name)."""
    text = str(text)
    return "'" + text if text[:1] in ("=", "+", "-", "@", "\t", "\r") else text


def row_notes(student_result):
    notes = []
    if student_result.result:
        notes += [f"{entry['id']} {entry['status']}" for entry in student_result.result["todos"]
                  if entry["status"] in ("time limit", "crashed", "not graded")]
    return "; ".join(notes)


def gradebook_row(student_result):
    row = [_cell(student_result.student), _cell(student_result.status)]
    row += [_points(student_result.auto_points(todo.id)) for todo in TODOS if todo.auto]
    row.append(_points(student_result.auto_total))
    row += ["" for todo in TODOS if todo.manual]
    row.append(_cell(row_notes(student_result)))
    return row


def gradebook_text(student_results):
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(gradebook_header())
    for student_result in sorted(student_results, key=lambda item: item.student):
        writer.writerow(gradebook_row(student_result))
    return stream.getvalue()


# ---- feedback --------------------------------------------------------------------------------


def _fence(text):
    """``text`` in a fenced code block whose fence no backtick run inside it can close."""
    longest = max((len(run) for run in re.findall(r"`+", text)), default=0)
    fence = "`" * max(3, longest + 1)
    return f"{fence}text\n{text.rstrip()}\n{fence}"


def md_escape(text):
    """Text a student's files may have shaped (notes, file names, statuses), safe inside a Markdown
    line: no emphasis, links, code, table cells or HTML."""
    text = str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("\n", " ")
    return re.sub(r"([\\`*_\[\]|~])", r"\\\1", text)


def todo_markdown(entry, visible_only=False):
    """One TODO of a result as Markdown: the points, what was checked, the first failing visible
    check with its input, expected and actual value, the notes. ``visible_only``: the checks'
    outcomes on the visible inputs only (a check that fails only on hidden inputs reads as passing)
    and no points, for feedback given before the grades are published."""
    lines = []
    if not visible_only and entry["auto_possible"]:
        lines.append(f"**{_points(entry['auto_earned'])} of {_points(entry['auto_possible'])} automatic point(s)** "
                     f"({entry['status']})")
    elif not entry["auto_possible"]:
        lines.append("Graded by hand" + ("; the check below is for the grader, it gives no points." if entry["checks"]
                                         else "."))
    if lines and entry["checks"]:
        lines.append("")
    for check in entry["checks"]:
        if visible_only:
            passed = check["passed"] or check["failed_on"] == "hidden"
            where = f"{check['visible_inputs']} visible input(s)"
            lines.append(f"- {'pass' if passed else '**FAIL**'}: {check['check']} ({where})")
            continue
        inputs = f"{check['visible_inputs']} visible"
        inputs += f", {check['hidden_inputs']} hidden" if check["hidden_inputs"] else ""
        where = f"; failed on a {check['failed_on']} input" if check["failed_on"] else ""
        lines.append(f"- {'pass' if check['passed'] else '**FAIL**'}, {_points(check['points'])} pt: "
                     f"{check['check']} ({inputs} input(s){where})")
    failure = entry["first_failure"]
    if failure and (not failure["hidden"] or not visible_only):
        headline, fields = failure_words(failure)  # the same words as every other report
        lines += ["", headline]
        for name, text in fields:
            lines += ["", f"{name}:", "", _fence(text)]
    notes = entry["notes"]
    if visible_only and not any(check["failed_on"] == "visible" for check in entry["checks"]):
        notes = [note for note in notes if not note.startswith(STOPPED_NOTE)]  # it may have stopped on a hidden input
    if notes:
        lines.append("")
        lines += [f"- note: {md_escape(note)}" for note in notes]
    if entry["manual_possible"] and not visible_only:
        lines.append("")
        lines.append(f"By hand ({_points(entry['manual_possible'])} pt): {md_escape(entry['manual'])}")
    return "\n".join(lines)


def summary_table(result):
    lines = ["| TODO | what | automatic | by hand | status |", "|---|---|---|---|---|"]
    for entry in result["todos"]:
        auto = "–"
        if entry["auto_possible"]:
            auto = f"{_points(entry['auto_earned'])} / {_points(entry['auto_possible'])}"
        manual = _points(entry["manual_possible"]) if entry["manual_possible"] else "–"
        lines.append(f"| {entry['id']} | {entry['title']} | {auto} | {manual} | {entry['status']} |")
    total = result["total"]
    lines.append(f"| **total** | | **{_points(total['auto_earned'])} / {_points(total['auto_possible'])}** | "
                 f"{_points(total['manual_possible'])} | |")
    return "\n".join(lines)


UNGRADED_HELP = (f"What the grader reads: your `{blocks.PACKAGE}/` folder (with the code between the "
                 "`### BEGIN TODO` and `### END TODO` markers), in a folder or a .zip, at the top or up to "
                 f"{KIT_DEPTH} folders down; plain files only (no links), each Python file under "
                 f"{_size(MAX_PY_BYTES)}.")


def feedback_markdown(student_result):
    """The feedback file of one student (Markdown): status, points per TODO, what was checked and
    the first failing visible check per TODO; never a hidden input."""
    lines = [f"# Homework 1, automatic grading: {md_escape(student_result.student)}", ""]
    lines.append(f"Status: **{md_escape(student_result.status)}**")
    result = student_result.result
    if result is None:
        lines += ["", "Automatic points: **0**. Nothing of this submission was run.", "", UNGRADED_HELP]
        return "\n".join(lines) + "\n"
    total = result["total"]
    lines += ["", f"Automatic points: **{_points(total['auto_earned'])} of {_points(total['auto_possible'])}**; "
                  f"{_points(total['manual_possible'])} more points are graded by hand."]
    lines += ["", "Each TODO is checked with your code for that TODO and the reference solution for every other "
                  "one, so a mistake costs points only where it was made."]
    for note in student_result.notes + result["notes"]:
        lines += ["", f"- note: {md_escape(note)}"]
    lines += ["", summary_table(result)]
    for entry in result["todos"]:
        if not entry["checks"] and not entry["notes"] and not entry["manual_possible"]:
            continue
        lines += ["", f"## {entry['id']} {entry['title']}", "", todo_markdown(entry)]
    return "\n".join(lines) + "\n"


def _write_if_changed(path, text):
    path = Path(path)
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except OSError:
        pass
    _write_atomically(path, text)


# ---- progress --------------------------------------------------------------------------------


def _clock(seconds):
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """Done/total, time elapsed and an estimate of the time left, on ``stream``. On a terminal: one
    line rewritten in place every second, and a line of its own for each submission that was not
    simply graded (rejected, unreadable, timed out...); elsewhere (a log file): one line per
    submission."""

    def __init__(self, total, stream=None):
        self.total, self.stream = total, stream
        self.done = self.graded_now = 0
        self.started = time.monotonic()
        self.tty = bool(stream is not None and getattr(stream, "isatty", lambda: False)())
        self.last = ""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        if self.tty:
            threading.Thread(target=self._tick, daemon=True, name="hwclass-progress").start()

    def line(self):
        elapsed = time.monotonic() - self.started
        left = self.total - self.done
        if left == 0:
            estimate = "done"
        elif self.graded_now == 0:
            estimate = "time left: estimating"
        else:
            estimate = f"about {_clock(elapsed / self.graded_now * left)} left"
        return f"[{self.done}/{self.total}] {_clock(elapsed)} elapsed, {estimate}"

    def _redraw(self):
        width = shutil.get_terminal_size((100, 24)).columns - 1
        self.stream.write("\r\x1b[K" + f"{self.line()}  {self.last}"[:width])
        self.stream.flush()

    def _tick(self):
        while not self._stop.wait(1.0):
            with self._lock:
                self._redraw()

    def update(self, student_result):
        if self.stream is None:
            return
        with self._lock:
            self.done += 1
            self.graded_now += student_result.result is not None and not student_result.reused
            what = f"{student_result.student}: {student_result.status}"
            if student_result.result is not None:
                what += f", {_points(student_result.auto_total)}/{_points(AUTO_POINTS)}"
            what += " (saved earlier)" if student_result.reused else f" ({student_result.seconds:.1f} s)"
            if not self.tty:
                self.stream.write(f"{self.line()}  {what}\n")
                self.stream.flush()
                return
            if student_result.status not in (GRADED, NOT_ISOLATED):  # kept on the screen
                self.stream.write(f"\r\x1b[K{what}\n")
            self.last = what
            self._redraw()

    def close(self):
        self._stop.set()
        if self.stream is not None and self.tty:
            with self._lock:
                self._redraw()
                self.stream.write("\n")
                self.stream.flush()


# ---- the run ---------------------------------------------------------------------------------


@dataclass
class ClassReport:
    """What ``grade_class`` did: ``students`` (StudentResult, sorted by id), the paths written, and
    how many submissions were graded now, reused from the saved state, or not gradable."""

    students: list
    gradebook: Path
    feedback: Path
    state: Path
    graded_now: int = 0
    reused: int = 0
    not_graded: int = 0
    errors: list = field(default_factory=list)


def cpu_count():
    """The CPUs this process may run on (a container's or a cpuset's share, where the system says)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def state_folder(gradebook):
    gradebook = Path(gradebook)
    return gradebook.parent / f".{gradebook.stem}-state"


def grade_class(submissions, gradebook, feedback, reference=None, *, jobs=None, grader=None, progress=None,
                **grader_options):
    """Grade every submission in the folder ``submissions`` against ``reference`` (the instructor's
    kit) and write the gradebook CSV ``gradebook`` and one Markdown file per student in ``feedback``.

    ``jobs``: submissions graded side by side (default: one per CPU), each in its own sandbox.
    ``grader``: a ``Grader`` to use (its reference answers are computed once, for the whole
    class); else one is made with ``grader_options`` (python, isolation, time_limit,
    memory_limit). ``progress``: a text stream for the progress line (None: silent). Returns a
    ``ClassReport``. A submission that cannot be read gets 0 and its reason; the others are graded.
    """
    submissions, gradebook, feedback = Path(submissions), Path(gradebook), Path(feedback)
    if not submissions.is_dir():
        raise GradingError(f"{submissions}: not a folder of submissions")
    jobs = int(jobs or cpu_count())
    if jobs < 1:
        raise GradingError(f"jobs must be at least 1, got {jobs}")
    if grader is None:
        if reference is None:
            raise GradingError("grading a class needs the instructor's kit as the reference (--reference KIT_DIR)")
        grader = Grader(reference, jobs=1, **grader_options)
    if grader.reference is None:
        raise GradingError("grading a class needs the instructor's kit as the reference, not an answer key: "
                           "the hidden checks decide points too")
    state = state_folder(gradebook)
    store = StateStore(state, grading_fingerprint(grader))
    found = find_submissions(submissions, skip=(gradebook, feedback, state))
    kit_names = kit_file_names(grader.layout)
    meter = Progress(len(found), progress)
    if progress is not None:
        how = grader.sandbox.how if grader.sandbox.isolated else f"NOT ISOLATED: {grader.sandbox.how}"
        progress.write(f"grading {len(found)} submission(s) in {submissions}, {jobs} at a time; sandbox: {how}\n")
        progress.flush()
    results, errors = [], []

    def task(student):
        try:
            return grade_one(grader, found[student], student, kit_names, store)
        except GradingError:
            raise
        except Exception as error:  # noqa: BLE001 - one submission's grading fault must not stop the class
            errors.append(f"{student}: {type(error).__name__}: {error}")
            return StudentResult(student, f"grader error: {type(error).__name__}: {error}")

    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="hwclass")
    try:
        futures = [pool.submit(task, student) for student in sorted(found)]
        for future in as_completed(futures):
            student_result = future.result()
            results.append(student_result)
            meter.update(student_result)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        meter.close()
        if progress is not None:
            progress.write(f"stopped: {sum(r.result is not None and not r.reused for r in results)} graded now and "
                           "saved; the submissions being graded finish and are saved before the program ends. Run the "
                           "same command again to go on from there.\n")
        raise
    pool.shutdown(wait=True)
    meter.close()
    results.sort(key=lambda item: item.student)
    _write_atomically(gradebook, gradebook_text(results))
    feedback.mkdir(parents=True, exist_ok=True)
    for student_result in results:
        _write_if_changed(feedback / f"{_safe_name(student_result.student)}.md", feedback_markdown(student_result))
    report = ClassReport(results, gradebook, feedback, state, errors=errors)
    for student_result in results:
        if student_result.result is None:
            report.not_graded += 1
        elif student_result.reused:
            report.reused += 1
        else:
            report.graded_now += 1
    return report


def main(args, parser):
    """The command line's batch mode (``python -m hwtools.grade SUBMISSIONS_DIR --gradebook ... --feedback ...``)."""
    if not args.gradebook or not args.feedback:
        parser.error(f"{args.submission}: no hwlib/ folder, so it is read as a folder of submissions (one folder or "
                     ".zip per student): give --gradebook FILE.csv and --feedback FOLDER (or give a kit's folder "
                     "to grade one kit)")
    for option, given in (("--todo", args.todo), ("--json", args.json), ("--answer-key", args.answer_key)):
        if given:
            parser.error(f"{option} is for grading one kit; a folder of submissions is graded whole")
    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    reference = args.reference
    if reference is None:
        if not has_solutions(KIT_ROOT):
            parser.error("grading a class needs the instructor's kit: pass --reference KIT_DIR")
        reference = KIT_ROOT
    try:
        report = grade_class(args.submission, args.gradebook, args.feedback, reference, jobs=args.jobs,
                             progress=sys.stderr, python=args.python, isolation=args.isolation,
                             time_limit=args.time_limit, memory_limit=args.memory_limit * 2**20)
    except GradingError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    print(f"{len(report.students)} submission(s): {report.graded_now} graded now, {report.reused} unchanged since "
          f"the saved results, {report.not_graded} not gradable (status in the gradebook)")
    print(f"gradebook: {report.gradebook}")
    print(f"feedback: {report.feedback}/ (one .md per student)")
    for error in report.errors:
        print(f"grader error (not saved; rerun to retry): {error}", file=sys.stderr)
    return 1 if report.errors else 0

"""The student's words in answers.tex, kept through every later report (standard library only).

The report writes answers.tex under a stamp line (the sha256 of the rest) and, beside it, the same text
as written (``.answers.tex.written``, hidden: not for editing). A student writes prose at its
``% Your words`` lines. When a later report (or hand-in) writes a new answers.tex where an edited one is,
``write_answers`` takes the student's changes (what differs between the text as written and their file)
into the new text, wherever the new report leaves those lines as they were: a three-way merge, as
``diff3`` makes one, of line ranges. Where both changed the same lines (the student edited a number the
new report changes too), nothing is merged: their file stays answers.tex as they wrote it, and the new
text goes beside it as answers.new.tex. (``write_answers`` does it; a hand-in, which builds the new
report in a folder of its own, names the old report's folder as ``words_from``.)
"""

from __future__ import annotations

import hashlib
import re
from difflib import SequenceMatcher
from pathlib import Path

from hwtools.files import replace_bytes

ANSWERS_TEX = "answers.tex"
AS_WRITTEN = ".answers.tex.written"  # the text the report last wrote, to tell the student's changes from it
NEW_TEX = "answers.new.tex"
# The first line of every answers.tex the report writes; the hash is that of the rest of the file.
STAMP = "% written by python -m hwtools.report; sha256 of the lines below: {digest}"
STAMP_LINE = re.compile(r"^% written by python -m hwtools\.report; sha256 of the lines below: ([0-9a-f]{64})\n")


def stamped(text):
    return _stamp(text) + text


def is_as_written(content):
    """Whether ``content`` (an answers.tex) is as the report wrote it: no words of the student's in it."""
    match = STAMP_LINE.match(content)
    return bool(match) and hashlib.sha256(content[match.end():].encode("utf-8")).hexdigest() == match.group(1)


def has_words(folder):
    """Whether the answers.tex in ``folder`` holds changes of the student's."""
    path = Path(folder) / ANSWERS_TEX
    return path.is_file() and not is_as_written(path.read_text(encoding="utf-8", errors="replace"))


def _changes(base, other):
    return [(i1, i2, other[j1:j2]) for tag, i1, i2, j1, j2 in SequenceMatcher(None, base, other, autojunk=False)
            .get_opcodes() if tag != "equal"]


def merge(base, ours, theirs):
    """``theirs`` (lines) with the changes ``ours`` made to ``base``, or None where both changed the same lines.
    An insertion where the other side replaces lines goes before them."""
    mine, new = _changes(base, ours), _changes(base, theirs)
    for i1, i2, _ in mine:
        for k1, k2, _ in new:
            if max(i1, k1) < min(i2, k2) or (i1 == i2 and k1 < i1 < k2) or (k1 == k2 and i1 < k1 < i2) or \
                    (i1 == i2 == k1 == k2):
                return None
    edits = sorted([(i1, i2, 0, lines) for i1, i2, lines in mine] + [(k1, k2, 1, lines) for k1, k2, lines in new])
    merged, at = [], 0
    for start, end, _, lines in edits:
        merged += base[at:start] + lines
        at = max(at, end)
    return merged + base[at:]


def combine(content, base, text):
    """What to write where the student's answers.tex ``content`` is and the report writes ``text`` anew (``base``:
    the text the report wrote last, None if unknown): (the new answers.tex, the text of answers.new.tex or None,
    a sentence saying which). Nothing of ``content`` is lost."""
    merged = None
    if base is not None:
        merged = merge(base.splitlines(True), _body(content).splitlines(True), text.splitlines(True))
    if merged is not None:
        merged = "".join(merged)
        return (stamped(text) if merged == text else _stamp(text) + merged, None,
                f"your words are kept in the new {ANSWERS_TEX}, with the new report's numbers")
    return (content, stamped(text), f"your {ANSWERS_TEX} is kept as you wrote it (it changes lines the new report "
            f"changes too); the new report's LaTeX is {NEW_TEX} beside it: carry your words into it, or its numbers into yours")


def write_answers(folder, text, words_from=None):
    """Write answers.tex (and its ``AS_WRITTEN`` copy) of the report's ``text`` into ``folder``, keeping the
    student's words from the answers.tex in ``words_from`` (default: ``folder``'s own); each file is written
    beside and swapped in. Returns the sentence of ``combine``, or None where there were no words."""
    folder = Path(folder)
    source = Path(words_from or folder)
    old = source / ANSWERS_TEX
    content = old.read_text(encoding="utf-8", errors="surrogateescape") if old.is_file() else None
    note, new_tex, written = None, None, text
    if content is None or is_as_written(content):
        answers = stamped(text)
    else:
        base = source / AS_WRITTEN
        base = base.read_text(encoding="utf-8") if base.is_file() else None
        answers, new_tex, note = combine(content, base, text)
        if new_tex is not None:  # their answers.tex stays as it was: so does the text it is compared with
            written = base
    for name, data in ((AS_WRITTEN, written), (NEW_TEX, new_tex), (ANSWERS_TEX, answers)):
        if data is not None:
            replace_bytes(folder / name, data.encode("utf-8", "surrogateescape"))
    return note


def _body(content):
    match = STAMP_LINE.match(content)
    return content[match.end():] if match else content


def _stamp(text):
    return STAMP.format(digest=hashlib.sha256(text.encode("utf-8")).hexdigest()) + "\n"

"""Text a student's files may have shaped (file names, ids, notes, error messages), made safe to show:
every control character (escape sequences, carriage returns, bidirectional overrides) becomes a
visible escape, so nothing a submission names can move the cursor, erase a line or reorder text
on the instructor's terminal, in the gradebook or in Markdown feedback; and every CSV cell the kit
writes shown as text by a spreadsheet (``spreadsheet_cell``, ``csv_text``)."""

from __future__ import annotations

import csv
import io
import unicodedata


def printable(text, keep_newlines=False):
    """``text`` with each control or format character (Unicode categories Cc and Cf: ESC, CR,
    BEL, U+202E...) shown as ``\\x1b``/``\\u202e``; newlines kept only if ``keep_newlines``."""
    out = []
    for char in str(text):
        if keep_newlines and char == "\n":
            out.append(char)
        elif unicodedata.category(char) in ("Cc", "Cf"):
            code = ord(char)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
        else:
            out.append(char)
    return "".join(out)


# Where a spreadsheet may see a formula: "=", "+", "-" or "@" in any of their compatibility forms
# (full-width ＝＋－＠, small ﹦﹢﹣﹫, super- and subscript ⁼⁺⁻₌₊₋: their NFKC form) or a minus or
# plus sign of its own (− U+2212, ➕➖, and ⁻₋, whose NFKC form is −), after any run of characters a spreadsheet may trim first:
# spaces of every kind (U+00A0, U+2000-U+200A, U+3000, ...), line and paragraph separators (U+2028,
# U+2029), control and format characters (tab, CR, LF, U+200B, U+FEFF, ...).
_TRIMMED = ("Zs", "Zl", "Zp", "Cc", "Cf")
_FORMULA_STARTS = ("=", "+", "-", "@")
_SIGNS = "\u2212\u2795\u2796"


def _may_start_a_formula(text):
    for char in text:
        category = unicodedata.category(char)
        if char.isspace() or category in _TRIMMED:
            continue
        first = unicodedata.normalize("NFKC", char)[:1]  # ⁻ and ₋ become −
        return first in _FORMULA_STARTS or (first and first in _SIGNS)
    return False


def spreadsheet_cell(value):
    """``value`` as a CSV cell that Excel, LibreOffice, Google Sheets and Canvas show as written: a
    number as it is; text made ``printable`` (one line, control characters escaped) and led by ``'``
    when it could start a formula, whatever leading spaces or look-alike characters come first."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    text = printable(value)
    return "'" + text if _may_start_a_formula(text) else text


def csv_text(rows):
    """``rows`` (sequences of cells) as CSV text with ``\\n`` line ends, every cell through
    ``spreadsheet_cell``: every CSV the kit writes is written here."""
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    for row in rows:
        writer.writerow([spreadsheet_cell(cell) for cell in row])
    return stream.getvalue()

"""Text a student's files may have shaped (file names, ids, notes, error messages), made safe to show:
every control character (escape sequences, carriage returns, bidirectional overrides) becomes a
visible escape, so nothing a submission names can move the cursor, erase a line or reorder text
on the instructor's terminal, in the gradebook or in Markdown feedback."""

from __future__ import annotations

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

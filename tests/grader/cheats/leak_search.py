"""The leak search of the grader's proof: every output a student may read, decoded as a cheat would
encode it, searched for the reference's lines and the hidden inputs' numbers.

``secrets_of(grader, layout)`` collects what no output may hold; ``assert_nothing_leaks(result,
secrets)`` decodes the text report, the JSON, the class feedback file and Gradescope's
results.json of one result (base64, base32, hex, zlib, gzip and raw deflate, three rounds deep;
truncated streams give what they hold) and fails on the first secret found.
"""

from __future__ import annotations

import base64
import binascii
import json
import re
import zlib

import numpy as np

from hwtools.grade import kits
from hwtools.grade.instructor import class_feedback, gradebook, gradescope_autograder
from hwtools.grade.feedback import render


def outputs_of(result):
    """Everything a student may read of ``result``: the text report, the JSON (as a class keeps it,
    without the grading's secret, the instructor's), the class feedback file and Gradescope's
    results.json."""
    student = gradebook.StudentResult("student", gradebook.status_of(result), result)
    public = {key: value for key, value in result.items() if key != "secret"}
    return [render(result), json.dumps(public), class_feedback.feedback_markdown(student),
            json.dumps(gradescope_autograder.results_json(result, gradebook.status_of(result)))]


def decodings(texts, rounds=3):
    """``texts`` as bytes, plus every base64, base32, hex and zlib/gzip/deflate decoding of what
    they contain, and of those again (``rounds`` deep; truncated streams give what they hold)."""
    found, frontier = set(), {text.encode("utf-8", "replace") for text in texts}
    for _ in range(rounds):
        found |= frontier
        fresh = set()
        for data in frontier:
            for wbits in (15, -15, 31):
                try:
                    inflated = zlib.decompressobj(wbits).decompress(data, 10_000_000)
                except zlib.error:
                    continue
                if inflated:
                    fresh.add(inflated)
            text = data.decode("latin-1")
            for token in set(re.findall(r"[A-Za-z0-9+/=_-]{16,}", text)):
                body = token.rstrip("=")
                candidates = []
                for alphabet in (None, b"-_"):
                    try:
                        candidates.append(base64.b64decode(body[:len(body) // 4 * 4], altchars=alphabet))
                    except (ValueError, binascii.Error):
                        pass
                if re.fullmatch(r"[0-9A-Fa-f]+", token):
                    candidates.append(bytes.fromhex(token[:len(token) // 2 * 2]))
                if re.fullmatch(r"[A-Z2-7=]+", token):
                    try:
                        candidates.append(base64.b32decode(body[:len(body) // 8 * 8]))
                    except (ValueError, binascii.Error):
                        pass
                fresh.update(candidate for candidate in candidates if len(candidate) >= 8)
        frontier = fresh - found
    return found


def secrets_of(grader, layout, case_sets=None):
    """What no output may hold: the lines of the reference's blocks (those not also in the kit's
    public code) and the hidden inputs' numbers (as text, strong formats, and as float64 bytes) of
    ``case_sets`` (a grading's: ``grader.case_sets(result["secret"])``; default the grader's own)."""
    public = "\n".join(kits.composite_files(layout, {}, set()).values())
    lines = [line for line in grader._scrub.lines if line not in public]
    strong, weak, raw = set(), [], set()
    for todo, cases in (case_sets or grader.cases).items():
        for case_id, _, args in cases.hidden:
            numbers = [float(v) for v in _floats(args) if abs(v) >= 1e-3 and len(f"{abs(v):.6g}".replace(".", "")) >= 5]
            for value in numbers:
                strong.update({repr(value), f"{value:.10g}", f"{value:.8f}"})
                raw.add(np.float64(value).tobytes())
            weak.append((case_id, {f"{value:.6g}" for value in numbers}))
    assert lines and strong and raw
    return {"lines": lines, "strong": strong, "weak": weak, "raw": raw}


def _floats(value):
    if isinstance(value, dict):
        return [item for part in value.values() for item in _floats(part)]
    if isinstance(value, (list, tuple)):
        return [item for part in value for item in _floats(part)]
    array = np.asarray(value)
    return list(array.ravel()) if array.dtype.kind == "f" else []


def assert_nothing_leaks(result, secrets):
    for data in decodings(outputs_of(result)):
        text = data.decode("utf-8", "replace")
        assert not result.get("secret") or result["secret"] not in text, "the grading's secret reached an output"
        line = next((line for line in secrets["lines"] if line in text), None)
        assert line is None, f"a line of the reference solution reached an output: {line!r}"
        number = next((number for number in secrets["strong"] if number in text), None)
        assert number is None, f"a hidden input's number reached an output: {number}"
        assert not any(pattern in data for pattern in secrets["raw"]), "a hidden input's bytes reached an output"
        for case_id, shown in secrets["weak"]:
            hits = [number for number in shown if number in text]
            assert len(hits) < 3, f"numbers of hidden input {case_id} reached an output: {hits}"

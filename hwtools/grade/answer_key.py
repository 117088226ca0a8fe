"""The student edition's answer key: the reference's values for the VISIBLE inputs of the exact checks,
and the known mistakes' signatures on those inputs with their one-line diagnoses.

The release tool writes it (``grader.write_answer_key``) into the student edition, where
``python -m hwtools.grade`` judges a student's own kit against it (the preview) and names the
known mistake a failing answer matches (``mistakes.py``): it holds nothing about hidden inputs and
no code. JSON; arrays as {dtype, shape, data}.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from hwtools.grade import mistakes
from hwtools.grade.in_sandbox.channel import fingerprint

ANSWER_KEY = Path(__file__).resolve().with_name("answer_key.json")
ANSWER_KEY_VERSION = 2


class AnswerKeyError(Exception):
    """An answer key that does not fit this grader (a GradingError for the caller)."""


def _encode_array(array):
    array = np.asarray(array)
    return {"dtype": str(array.dtype), "shape": list(array.shape), "data": array.ravel().tolist()}


def _decode_array(data):
    return np.array(data["data"], dtype=data["dtype"]).reshape(data["shape"])


def visible_digest(cases):
    """A digest of every visible case of ``cases`` ({todo: CaseSet}): the key fits only these."""
    digest = hashlib.sha256()
    for todo in sorted(cases):
        for case_id, _, args in cases[todo].visible:
            digest.update(fingerprint({"id": case_id, "args": args}).encode() + b"\0")
    return digest.hexdigest()


def mistake_digest(wrong):
    """A digest of one known mistake (a ``mistakes.WrongSolution``: its words and code): the key records
    one per known mistake it was written with, so a newer or changed one shows (``instructor/gate.py``)."""
    fields = [wrong.todo, wrong.file, wrong.mistake, wrong.diagnosis, wrong.rule, list(wrong.bodies)]
    return hashlib.sha256(json.dumps(fields).encode()).hexdigest()[:16]


def write(expected, cases, out_path, known=(), sources=()):
    """Write the key: ``expected`` {case id: {name: array}} of visible exact cases, ``known`` the
    known mistakes' table (``mistakes.py``: signatures on the visible inputs, diagnoses), ``sources``
    the known mistakes it was made from (``WrongSolution``s: their digests are recorded)."""
    key = {"version": ANSWER_KEY_VERSION, "visible_cases": visible_digest(cases),
           "expected": {case_id: {name: _encode_array(value) for name, value in values.items()}
                        for case_id, values in expected.items()},
           "mistakes": mistakes.encode(list(known), _encode_array),
           "known_mistakes": {wrong.id: mistake_digest(wrong) for wrong in sources}}
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(key, sort_keys=True, separators=(",", ":")) + "\n", encoding="utf-8")
    return out_path


def read(path):
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    if data.get("version") != ANSWER_KEY_VERSION:
        raise AnswerKeyError(f"{path}: answer key version {data.get('version')}, this grader reads {ANSWER_KEY_VERSION}")
    data["expected"] = {case_id: {name: _decode_array(value) for name, value in values.items()}
                        for case_id, values in data["expected"].items()}
    data["mistakes"] = mistakes.decode(data.get("mistakes", []), _decode_array)
    return data


def check_matches(key, cases):
    if key.get("visible_cases") != visible_digest(cases):
        raise AnswerKeyError("the answer key was written for other visible checks than this grader's: "
                             "rebuild the student edition (python -m instructor.release student OUT)")

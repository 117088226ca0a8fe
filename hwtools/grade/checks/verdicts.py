"""How a check's answer is judged and shown: the verdict of one input, tolerances, and the words of a difference.

``exact(name, tolerance, locate)`` makes a judge that compares value ``name`` with the
reference's; ``difference_words`` is the one wording of where two arrays of numbers differ most (the
student's preview, the instructor's grade, the class feedback and Gradescope all show it);
``show`` writes a value short for feedback. Standard library and numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Verdict:
    """What one input gave: passed or not, the expected and the actual value in short, and for an
    answer of numbers, where they differ most (``difference``, from ``difference_words``) and what
    counts as equal (``tolerance``, ``Tolerance.words``). ``summary``: what is wrong in one clause,
    expected against actual where they differ most ("at coordinate 2: expected 1.5, actual 3"), the
    first line of every report of a failure (``feedback.first_lines``)."""

    passed: bool
    expected: str = ""
    actual: str = ""
    difference: str = ""
    tolerance: str = ""
    rule: str = ""  # a known mistake the judge sees by rule (``mistakes.py``: a wrong solution's "# rule:")
    summary: str = ""


def _number_text(number, digits=6):
    number = float(number)
    if number == 0 or not np.isfinite(number):
        return "0" if number == 0 else str(number)
    return f"{number:.{digits}g}"


def show(value, limit=12):
    """A short text of ``value`` for feedback: at most ``limit`` numbers, 6 significant digits each
    (so that 2.4e-11 reads 2.4e-11, never 0)."""
    if isinstance(value, dict):
        return ", ".join(f"{key}={show(item, limit)}" for key, item in value.items())
    if isinstance(value, (list, tuple)) and not all(isinstance(item, (int, float, bool)) for item in value):
        return "[" + ", ".join(show(item, limit) for item in value) + "]"
    if isinstance(value, str):
        return value
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        return f"<{type(value).__name__}>"
    if array.ndim == 0:
        return _number_text(array.item()) if array.dtype.kind == "f" else str(array.item())
    items = array.ravel()[:limit]
    texts = [_number_text(item) for item in items] if array.dtype.kind == "f" else [str(item) for item in items.tolist()]
    text = "[" + ", ".join(texts) + (", ...]" if array.size > limit else "]")
    more = f" ({array.size} values)" if array.size > limit else ""
    shape = f" shape {array.shape}" if array.ndim > 1 else ""
    return text + more + shape


def tell_apart(expected, actual):
    """``expected`` and ``actual`` as texts with as many significant digits (6 at least, 17 at
    most) as it takes for the two to read differently."""
    expected, actual = float(expected), float(actual)
    if all(np.isfinite(v) and v.is_integer() and abs(v) < 1e15 for v in (expected, actual)):
        return str(int(expected)), str(int(actual))
    for digits in range(6, 18):
        texts = _number_text(expected, digits), _number_text(actual, digits)
        if texts[0] != texts[1]:
            break
    return texts


@dataclass(frozen=True)
class Tolerance:
    """When an actual number counts as the expected one: |actual - expected| <= rtol * |expected| + atol,
    with ``loose_atol`` in place of ``atol`` where ``loose(args)`` (booleans shaped like the answer)
    holds. ``why`` says why these limits fit the computation; ``words()`` says it all."""

    rtol: float
    atol: float
    why: str = ""
    loose_atol: float = 0.0
    loose: object = None  # loose(args) -> booleans shaped like the answer: where loose_atol applies
    loose_words: str = ""

    def limits(self, expected, args):
        expected = np.asarray(expected, dtype=np.float64)
        atol = np.full(expected.shape, self.atol)
        if self.loose is not None:
            atol = np.where(np.asarray(self.loose(args), dtype=bool).reshape(expected.shape), self.loose_atol, atol)
        return self.rtol * np.abs(expected) + atol

    def words(self):
        if self.rtol == 0 and self.atol == 0:
            text = "exactly equal"
        elif self.rtol == 0:
            text = f"|actual - expected| <= {self.atol:g}"
        else:
            text = f"|actual - expected| <= {self.rtol:g} * |expected|" + (f" + {self.atol:g}" if self.atol else "")
        if self.loose is not None:
            text += f"; + {self.loose_atol:g} in place of + {self.atol:g} {self.loose_words}"
        return text + (f"; {self.why}" if self.why else "")


EXACTLY = Tolerance(0.0, 0.0)


def same_numbers(actual, expected):
    """(``actual`` arranged as ``expected``, None), or (None, why not). Right: the same shape, or,
    where the answer is one number or one row of N numbers, any N numbers in a row (a list, an
    array of shape (N,); (1,) or a bare number for a single one)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    if actual.shape == expected.shape:
        return actual, None
    if actual.size == expected.size and actual.ndim <= 1 and expected.ndim <= 1:
        return actual.reshape(expected.shape), None
    if actual.ndim <= 1 and expected.ndim <= 1:
        return None, f"{actual.size} number(s), where {expected.size} are expected"
    return None, f"an array of shape {actual.shape}, where shape {expected.shape} is expected"


def difference_words(actual, expected, tolerance=EXACTLY, args=None, locate=None):
    """(passed, words, summary): whether ``actual`` equals ``expected`` within ``tolerance`` (every
    entry finite), and if not, where they differ most (the entry farthest outside the tolerance, a
    NaN or infinity first), in words: the index (with what ``locate(args, index)`` says about that
    entry's input: "coordinate 2: x[2] = ...", whose part before ": " names the entry in short),
    expected and actual with enough digits to tell them apart, the difference, absolute and
    relative, and how many entries differ; ``summary`` is the same in one clause ("at coordinate 2:
    expected 1.5, actual 3"). This is the one wording of a difference; every report (the preview,
    the grade, the class's feedback, Gradescope) shows it."""
    arranged, wrong_shape = same_numbers(actual, expected)
    if wrong_shape:
        return False, f"the answer is {wrong_shape}", f"the answer is {wrong_shape}"
    actual = np.asarray(arranged, dtype=np.float64)
    expected = np.asarray(expected, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        limits = tolerance.limits(expected, args)
        gap = np.abs(actual - expected)
        bad = ~np.isfinite(actual) | ~(gap <= limits)
        excess = np.where(np.isfinite(actual), gap / np.maximum(limits, np.finfo(np.float64).tiny), np.inf)
    if not bad.any():
        return True, "", ""
    flat = int(np.argmax(np.where(bad.ravel(), excess.ravel(), -1.0)))
    index = tuple(int(i) for i in np.unravel_index(flat, expected.shape))
    want, got = float(expected[index]), float(actual[index])
    context = locate(args, index) if locate is not None and args is not None else ""
    where = f"index [{', '.join(map(str, index))}]" if index else ""
    head = (f"differs most at {where}" if expected.size > 1 else f"differs at {where}") if where else "the value differs"
    head += f" ({context})" if context else ""
    want_text, got_text = tell_apart(want, got) if np.isfinite(got) else (tell_apart(want, want)[0], str(got))
    words = f"{head}: expected {want_text}, actual {got_text}"
    if np.isfinite(got) and not (tolerance == EXACTLY and want.is_integer() and got.is_integer()):
        words += f"; difference {abs(got - want):.3g}, " + (f"relative difference {abs(got - want) / abs(want):.3g}"
                                                          if want != 0 else
                                                          "relative difference undefined (the expected value is 0)")
    if expected.size > 1:
        words += f"; {int(bad.sum())} of {expected.size} entries differ"
    short = context.split(": ", 1)[0] if context else where
    summary = (f"at {short}: " if short else "") + f"expected {want_text}, actual {got_text}"
    if expected.size > 1:
        summary += f" ({int(bad.sum())} of {expected.size} differ)"
    return False, words, summary


def _close(actual, expected, rtol, atol):
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    return actual.shape == expected.shape and bool(np.all(np.isfinite(actual))) and \
        bool(np.allclose(actual, expected, rtol=rtol, atol=atol))


def exact(name, tolerance=EXACTLY, locate=None, rule=None):
    """A judge: value ``name`` equals the reference's within ``tolerance`` (``difference_words``).
    ``rule(args, actual, expected, tolerance, result)``: the known mistake a wrong answer shows whatever
    its constant ("rounds_observation", ...; ``mistakes.py``), or "": asked only when the answer is wrong.""" 

    def judge(args, result, expected, services):
        want = expected[name]
        if result["status"] != "ok":
            return Verdict(False, show(want), result["error"], summary=f"expected the {name}, actual {result['error']}")
        actual = result["values"][name]
        passed, words, summary = difference_words(actual, want, tolerance, args, locate)
        seen = "" if passed or rule is None else _rule_of(rule, args, actual, want, tolerance, result)
        return Verdict(passed, show(want), show(actual), words, "" if passed else tolerance.words(), seen, summary)

    judge.tolerance = tolerance
    return judge


def _rule_of(rule, args, actual, expected, tolerance, result):
    """What ``rule`` sees in a wrong answer of the right shape, or "" (an answer it cannot read is no mistake it knows)."""
    arranged, wrong_shape = same_numbers(actual, expected)
    if wrong_shape:
        return ""
    try:
        with np.errstate(all="ignore"):
            return rule(args, np.asarray(arranged, dtype=np.float64), np.asarray(expected, dtype=np.float64), tolerance,
                        result)
    except (ValueError, TypeError, KeyError, IndexError, FloatingPointError, OverflowError):
        return ""


def close_to(actual, wanted, tolerance, args=None):
    """Every entry of ``actual`` within ``tolerance`` of ``wanted`` (finite), as the judges compare."""
    actual, wanted = np.asarray(actual, dtype=np.float64), np.asarray(wanted, dtype=np.float64)
    if actual.shape != wanted.shape:
        return False
    with np.errstate(invalid="ignore", over="ignore"):
        return bool(np.all(np.isfinite(actual) & (np.abs(actual - wanted) <= tolerance.limits(wanted, args))))

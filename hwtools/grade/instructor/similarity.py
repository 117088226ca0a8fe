"""A similarity report per TODO, offline: which pairs of students wrote a TODO's block alike.

    python -m hwtools.grade SUBMISSIONS_DIR --similarity OUT_DIR

Each submission is read as the class run reads it (``submissions.open_submission``, then the
grader's own reader, ``blocks.read_submission``: only the code between a TODO's markers), and each
TODO's blocks are compared pair by pair with copydetect (PyPI, MIT: the winnowing of MOSS's authors,
computed here; nothing leaves the machine). Its tokenizer reads every name as "V" and drops comments
and white space, so a renamed variable, an added comment or a re-indented line changes nothing;
its k-gram fingerprints survive reordered lines and a changed constant in part.

What every student would write is no evidence (``Fingerprints``): a TODO's boilerplate (the student
edition's stub, the handout's equations as code: ``HANDOUT_CODE``) never counts, and, as with MOSS's
``-m``, a fingerprint found in more than ``common_limit`` students' blocks of a TODO is how the
class writes it, not a copy. For a pair of students and a TODO, ``own`` is how much of the two
blocks is shared beyond the boilerplate, and ``across`` how much of what each wrote rarely, over all
TODOs, the two share: one student who copies another's homework shares the other's rare code in
every TODO, two who happen to write one TODO alike do not. The rare code is read with each block's
statements in one order (``statement_order``), so that reordered lines hide nothing of it. The
``score``, (own + 2 across) / 3, ranks the pairs of each TODO and flags those at ``FLAG`` or more.
Two students flagged elsewhere, one of whose blocks of a TODO is nothing but the boilerplate (the
handout's formula, say), are listed there as no evidence (``Report.handout_only``), not ranked: an
honest pair would look the same.

``OUT_DIR/similarity.csv`` lists each TODO's best ``TOP`` pairs (with the other TODOs where the
same two are flagged); ``OUT_DIR/similarity.html`` shows them, with the two blocks side by side and
the shared code marked, every student text escaped, nothing loaded from anywhere.
"""

from __future__ import annotations

import ast
import builtins
import copy
import html
import io
import itertools
import keyword
import sys
import tokenize
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from copydetect.detector import CodeFingerprint, compare_files
from copydetect.utils import filter_code, get_token_coverage

from hwtools.grade import blocks
from hwtools.grade.grader import KIT_ROOT, has_solutions
from hwtools.grade.instructor import classroom
from hwtools.grade.instructor.classroom import _write_atomically, find_submissions
from hwtools.grade.safe_text import csv_text, printable
from hwtools.grade.submissions import Unusable, kit_file_names, open_submission
from hwtools.todos import TODO_BY_ID

# Tuned on benchmarks/bench_similarity.py's classes (RESULTS.md): k = 16 and 8 missed more copies, a
# winnowing window of 3 and a common limit of 10% flagged more independent pairs; k below 12 for the TODOs
# of short blocks only (``noise``) found the copies with one constant changed that 12 missed.
NOISE = 12  # k: a fingerprint is 12 characters of the tokenized block ("V=V.V(V)+..."); shorter matches are noise
SHORTEST = 8  # the least k, for a TODO whose median block is 32 such characters or fewer
WINDOW = 1  # every k-gram is a fingerprint (the blocks are short: winnowing would only lose matches)
FLAG = 0.6  # the score from which a pair is flagged
TOP = 25  # pairs per TODO in the CSV and the page
SIDE_BY_SIDE = 10  # pairs per TODO shown with their blocks

# The handout's equations as a student writes them with the kit's names: boilerplate, with the stub.
HANDOUT_CODE = {
    "1.1.1": "action = int(np.dot(self.params, obs) < 0)\naction = 1 if self.params @ obs < 0 else 0",
    "1.2.1": "for i in range(len(x)):\n    gradient[i] = (f(x + h[i] * e) - f(x - h[i] * e)) / (2 * h[i])",
    "1.3.1": "for k in range(num_rollouts):\n    total += run_policy(policy, seed=seed + k)\n"
             "mean_reward = total / num_rollouts",
    "1.3.2": "gradient = scalar_finite_diff(g, params, fd_step)\nparams = params + learning_rate * gradient\n"
             "rewards.append(eval_params(params, num_rollouts_per_eval, seed=eval_seed))",
    "2.1.1": "gradient = features_aug.T @ (labels - sigmoid(features_aug @ weights))",
    "2.2.1": "values = 1 / (1 + np.exp(-z))",
    "2.2.2": "X_aug = np.hstack([X, np.ones((X.shape[0], 1))])\nprobabilities = sigmoid(X_aug @ self.weights)",
    "2.2.3": "gradient = X_aug.T @ (y - sigmoid(X_aug @ self.weights))\n"
             "self.weights = self.weights + learning_rate * gradient",
    "2.3.1": "labels = (y == c).astype(int)\nself.classifiers[c].gradient_ascent_step(X, labels, learning_rate)",
}


def common_limit(students):
    """A fingerprint in more blocks than this is how the class writes the TODO, not a copy: 5% of
    the class, at least 2 (a pair always counts)."""
    return max(2, students // 20)


def block_text(body):
    """One TODO's code (its blocks' lines, a tuple per block) as one text, indented as at the top."""
    return "\n\n".join("\n".join(blocks.reindent(lines, "")) for lines in body) + "\n"


def boilerplate_texts(block):
    """A block's boilerplate: the stub the student starts from, and the handout's equations."""
    stub = list(block.stub) + [f'raise TodoNotDone("{block.todo}")']
    return "\n".join(blocks.reindent(stub, "")) + "\n", HANDOUT_CODE.get(block.todo, "") + "\n"


def todo_blocks(layout):
    """{todo: its first block in the kit ``layout``}, in the files' order."""
    found = {}
    for file_blocks in layout.blocks_by_file.values():
        for block in file_blocks:
            found.setdefault(block.todo, block)
    return found


KEPT = {*vars(builtins), "self"}  # names copydetect's lexer keeps (pygments: Name.Builtin, Name.Builtin.Pseudo)


def _shape(line):
    """A statement's tokens as copydetect reads them: every name "V", but keywords and ``KEPT``."""
    def read(token):
        kept = token.type != tokenize.NAME or token.string in KEPT or keyword.iskeyword(token.string)
        return token.string if kept else "V"
    return "".join(map(read, tokenize.generate_tokens(io.StringIO(line).readline)))


def statement_order(text):
    """``text``'s statements in one order, that of their ``_shape``, without comments: blocks that
    differ only in the order of their lines (or names, or comments) read alike. Code that does not
    parse is left as it is."""
    try:
        lines = [ast.unparse(statement) for statement in ast.parse(text).body]
    except (SyntaxError, ValueError, RecursionError):
        return text
    return "\n".join(sorted(lines, key=_shape)) + "\n"


def read_class(folder, layout, skip=()):
    """({student: {todo: text}}, {student: why not read}) of the submissions in ``folder``."""
    texts, unread = {}, {}
    names = kit_file_names(layout)
    for student, paths in find_submissions(folder, skip).items():
        if len(paths) > 1:
            unread[student] = f"more than one submission under this id ({', '.join(path.name for path in paths)})"
            continue
        try:
            with open_submission(paths[0], names) as opened:
                submission = blocks.read_submission(opened.kit, layout)
        except Unusable as unusable:
            unread[student] = unusable.text
            continue
        texts[student] = {todo: block_text(body) for todo, body in submission.bodies.items()}
        if not texts[student]:
            unread[student] = "no TODO block could be read"
    return texts, unread


def _fingerprint(text, todo, k=NOISE):
    return CodeFingerprint(f"{todo}.py", k, WINDOW, language="python", fp=io.StringIO(text))


def _without(found, ignored):
    """A copy of the fingerprint ``found`` without the hashes in ``ignored``."""
    kept = copy.copy(found)
    kept.hashes = found.hashes - ignored
    kept.hash_idx = {value: where for value, where in found.hash_idx.items() if value in kept.hashes}
    kept.token_coverage = get_token_coverage(kept.hash_idx, found.k, len(found.filtered_code))
    return kept


def noise(texts):
    """k for one TODO's blocks ``texts``: a quarter of the median block's length as copydetect reads it,
    from ``SHORTEST`` to ``NOISE``, so that the pieces of a short block cut by a changed constant or by
    moved lines still hold k-grams."""
    lengths = sorted(len(filter_code(text, "block.py", "python")[0]) for text in texts)
    return max(SHORTEST, min(NOISE, lengths[len(lengths) // 2] // 4)) if lengths else NOISE


class Fingerprints:
    """One TODO's blocks fingerprinted two ways: ``plain`` without the boilerplate's fingerprints
    (the stub, the handout's equations: ``boilerplate``, texts), ``rare`` from the blocks with their
    statements in one order (``statement_order``), without the boilerplate's and those in more than
    ``limit`` students' blocks (how the class writes it): only the rare ones are evidence."""

    def __init__(self, todo, texts, boilerplate, limit):
        self.todo = todo
        k = noise(texts.values())
        boilerplate = set().union(*(_fingerprint(form, todo, k).hashes for text in boilerplate
                                    for form in (text, statement_order(text))))
        self.plain = {student: _without(_fingerprint(text, todo, k), boilerplate) for student, text in texts.items()}
        ordered = {student: _without(_fingerprint(statement_order(text), todo, k), boilerplate)
                   for student, text in texts.items()}
        counts = {}
        for found in ordered.values():
            for value in found.hashes:
                counts[value] = counts.get(value, 0) + 1
        common = {value for value, count in counts.items() if count > limit}
        self.rare = {student: _without(found, common) for student, found in ordered.items()}


def _compare(first, second):
    """(the mean of the two blocks' shares of what they share, the shares, the shared slices)."""
    if not (first.token_coverage and second.token_coverage):
        return 0.0, (0.0, 0.0), (np.zeros((2, 0)), np.zeros((2, 0)))
    overlap, shares, slices = compare_files(first, second)
    shares = tuple(min(1.0, float(share)) for share in shares) if overlap else (0.0, 0.0)
    return sum(shares) / 2, shares, slices


@dataclass
class Pair:
    """Two students' blocks of one TODO: ``own`` (the mean of ``shares``, each block's share of what
    the two share beyond the boilerplate), ``across`` (the evidence: the same measure on the rare
    fingerprints only, averaged over every TODO where both wrote something rare), ``score`` (what
    ranks and flags the pair: ``own`` and twice ``across``, averaged), the shared code's ``slices``
    in each block's text."""

    todo: str
    students: tuple
    own: float
    shares: tuple
    slices: tuple
    across: float
    rank: int = 0
    also: list = field(default_factory=list)  # the other TODOs where the same two are flagged

    @property
    def score(self):
        return (self.own + 2 * self.across) / 3

    @property
    def flagged(self):
        return self.score >= FLAG


def _sharing(prints):
    """The pairs of students whose fingerprints ``prints`` share a hash."""
    by_hash = {}
    for student in sorted(prints):
        for value in prints[student].hashes:
            by_hash.setdefault(value, []).append(student)
    return {pair for sharing in by_hash.values() for pair in itertools.combinations(sharing, 2)}


@dataclass
class Report:
    """What ``similarity`` found: ``pairs`` {todo: [Pair], best first}, ``texts`` {student: {todo:
    text}}, ``unread`` {student: why}, ``silent`` {todo: why nothing in it is evidence},
    ``handout_only`` {todo: [Pair]}: pairs flagged in other TODOs where one of the two blocks of this
    one is nothing but the stub and the handout's equations (not evidence, not ranked)."""

    pairs: dict
    texts: dict
    unread: dict
    silent: dict
    handout_only: dict


def similarity(folder, layout, skip=()):
    """The ``Report`` of the submissions in ``folder`` against the kit ``layout`` (the reference's)."""
    return compare_class(*read_class(folder, layout, skip), layout)


def compare_class(texts, unread, layout):
    """The ``Report`` of ``texts`` ({student: {todo: text}}; ``unread``: {student: why not read})."""
    limit = common_limit(len(texts))
    todos = {}
    for todo, block in todo_blocks(layout).items():
        found = {student: each[todo] for student, each in texts.items() if todo in each}
        todos[todo] = Fingerprints(todo, found, boilerplate_texts(block), limit)
    evidence, rare_in = {}, {}  # pair -> summed rare shares; student -> TODOs where they wrote something rare
    for todo, prints in todos.items():
        for student, found in prints.rare.items():
            if found.token_coverage:
                rare_in.setdefault(student, set()).add(todo)
        for pair in _sharing(prints.rare):
            evidence[pair] = evidence.get(pair, 0.0) + _compare(*(prints.rare[student] for student in pair))[0]
    across = {pair: total / len(rare_in[pair[0]] & rare_in[pair[1]]) for pair, total in evidence.items()}
    pairs, silent, unshared = {}, {}, {}
    for todo, prints in todos.items():
        found = []
        for pair in sorted(across):
            if all(student in prints.plain for student in pair):
                own, shares, slices = _compare(*(prints.plain[student] for student in pair))
                (found if own else unshared.setdefault(todo, [])).append(
                    Pair(todo, pair, own, shares, slices, across[pair]))
        found.sort(key=lambda pair: (-pair.score, -pair.own, pair.students))
        for rank, pair in enumerate(found, 1):
            pair.rank = rank
        pairs[todo] = found
        if not any(each.token_coverage for each in prints.rare.values()):
            silent[todo] = ("every block is the stub, the handout's equations or what more than "
                            f"{limit} students wrote alike: nothing in it tells copying from agreement; its pairs "
                            "are those the other TODOs give evidence on")
    pairs = {todo: pairs[todo] for todo in sorted(pairs, key=lambda todo: tuple(int(part) for part in todo.split(".")))}
    flagged = {}
    for todo, found in pairs.items():
        for pair in found:
            if pair.flagged:
                flagged.setdefault(pair.students, []).append(todo)
    handout_only = {}  # pairs flagged elsewhere, one of whose blocks here has nothing beyond the boilerplate
    for todo, found in unshared.items():
        found = [pair for pair in found if pair.students in flagged
                 and not all(todos[todo].plain[student].token_coverage for student in pair.students)]
        if found and todo not in silent:
            handout_only[todo] = found
    for todo, found in (*pairs.items(), *handout_only.items()):
        for pair in found:
            pair.also = [other for other in flagged.get(pair.students, []) if other != todo]
    return Report(pairs, texts, unread, silent, handout_only)


CSV_HEADER = ("todo", "rank", "student_a", "student_b", "score", "this_todo", "all_todos", "share_of_a", "share_of_b",
              "flagged", "also_flagged_in")
NOT_EVIDENCE = "not evidence: a block that is only the handout's equations"


def csv_report(report):
    """The ranked table: each TODO's ``TOP`` pairs, best first, then its ``handout_only`` pairs, unranked."""
    rows = [CSV_HEADER]
    for todo, found in report.pairs.items():
        rows += [(todo, pair.rank, *pair.students, round(pair.score, 3), round(pair.own, 3), round(pair.across, 3),
                  *(round(share, 3) for share in pair.shares),
                  "yes" if pair.flagged else "", " ".join(pair.also)) for pair in found[:TOP]]
        rows += [(todo, "", *pair.students, "", 0, round(pair.across, 3), "", "", NOT_EVIDENCE, " ".join(pair.also))
                 for pair in report.handout_only.get(todo, [])]
    return csv_text(rows)


def _marked(text, slices):
    """``text`` escaped, with the shared code's slices in <mark>."""
    out, position = [], 0
    for start, end in sorted(zip(*(np.asarray(part, dtype=int).tolist() for part in slices))):
        start, end = max(start, position), min(end, len(text))
        if start >= end:
            continue
        out += [html.escape(text[position:start]), "<mark>", html.escape(text[start:end]), "</mark>"]
        position = end
    out.append(html.escape(text[position:]))
    return "".join(out)


def _shown(text):
    return html.escape(printable(text))


PAGE_STYLE = """body{font-family:system-ui,sans-serif;margin:1.5em;max-width:110em}table{border-collapse:collapse}
td,th{border:1px solid #bbb;padding:.2em .5em;text-align:left;vertical-align:top}pre{margin:0;white-space:pre-wrap}
mark{background:#ffd54f}.flag{font-weight:bold;color:#b00020}.pair td{width:50%}"""


def html_report(report, title="Similarity per TODO"):
    """A page an instructor reads: per TODO the ranked pairs, then the first ``SIDE_BY_SIDE`` and
    every flagged one with their two blocks side by side, the shared code marked. Every student
    text is escaped; the page loads nothing from anywhere."""
    students = len(report.texts)
    parts = [f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{html.escape(title)}</title>",
             f"<style>{PAGE_STYLE}</style></head><body><h1>{html.escape(title)}</h1>",
             f"<p>{students} submissions compared, TODO by TODO. Each TODO's pairs are ranked by a score from 0 "
             "to 1: how much of their two blocks the two share beyond the TODO's stub and the handout's equations "
             "(<i>this TODO</i>) and, counted twice, how much of what each wrote that few others wrote the two share "
             f"over all TODOs (<i>all TODOs</i>; code found in more than {common_limit(students)} submissions is how "
             f"the class writes it, not evidence). From {FLAG:g} on a pair is flagged. A high score is a reason to "
             "read the two blocks, not a finding.</p>"]
    if report.unread:
        parts.append("<h2>Not compared</h2><ul>" + "".join(f"<li>{_shown(student)}: {_shown(why)}</li>"
                                                            for student, why in sorted(report.unread.items())) + "</ul>")
    for todo, found in report.pairs.items():
        info = TODO_BY_ID.get(todo)
        parts.append(f"<h2 id='todo-{todo}'>TODO {todo} {html.escape(info.title if info else '')}</h2>")
        if todo in report.silent:
            parts.append(f"<p>{html.escape(report.silent[todo])}.</p>")
            continue
        flagged = sum(pair.flagged for pair in found)
        parts.append(f"<p>{flagged} pair(s) flagged of the {len(found)} that share code here and rare code somewhere.</p>")
        if todo in report.handout_only:
            parts.append("<p>Flagged in other TODOs, but here one of the two wrote nothing but the stub and the "
                         "handout's equations (not evidence: an honest student writes the same): " + "; ".join(
                             f"{_shown(pair.students[0])} &amp; {_shown(pair.students[1])} (flagged in "
                             f"{html.escape(' '.join(pair.also))})" for pair in report.handout_only[todo]) + ".</p>")
        if not found:
            continue
        parts.append("<table><tr><th>rank</th><th>students</th><th>score</th><th>this TODO</th><th>all TODOs</th>"
                     "<th>also flagged in</th></tr>")
        for pair in found[:TOP]:
            mark = " class=flag" if pair.flagged else ""
            link = (f"<a href='#pair-{todo}-{pair.rank}'>{pair.rank}</a>"
                    if pair.rank <= SIDE_BY_SIDE or pair.flagged else str(pair.rank))
            parts.append(f"<tr><td>{link}</td><td>{_shown(pair.students[0])} &amp; {_shown(pair.students[1])}</td>"
                         f"<td{mark}>{pair.score:.2f}</td><td>{pair.own:.2f}</td><td>{pair.across:.2f}</td>"
                         f"<td>{html.escape(' '.join(pair.also))}</td></tr>")
        parts.append("</table>")
        for pair in found[:TOP]:
            if pair.rank > SIDE_BY_SIDE and not pair.flagged:
                continue
            first, second = pair.students
            parts.append(f"<h3 id='pair-{todo}-{pair.rank}'>{todo}, rank {pair.rank}: {_shown(first)} &amp; "
                         f"{_shown(second)}, score {pair.score:.2f}</h3><table class=pair><tr>"
                         f"<th>{_shown(first)} ({pair.shares[0]:.0%} shared)</th>"
                         f"<th>{_shown(second)} ({pair.shares[1]:.0%} shared)</th></tr><tr>"
                         f"<td><pre>{_marked(report.texts[first][todo], pair.slices[0])}</pre></td>"
                         f"<td><pre>{_marked(report.texts[second][todo], pair.slices[1])}</pre></td></tr></table>")
    parts.append("</body></html>\n")
    return "".join(parts)


def report_paths(out):
    out = Path(out)
    return out / "similarity.csv", out / "similarity.html"


def write_report(folder, out, layout, skip=()):
    """Compare the submissions in ``folder`` and write the CSV and the page into the folder ``out``."""
    out = Path(out)
    report = similarity(folder, layout, skip=(*skip, out))
    table, page = report_paths(out)
    _write_atomically(table, csv_report(report))
    _write_atomically(page, html_report(report))
    return report


def main(args, parser):
    """``python -m hwtools.grade SUBMISSIONS_DIR --similarity OUT_DIR [--gradebook ... --feedback ...]``:
    the report first (no student code runs: it needs no sandbox), then the class run if asked for."""
    for option, given in (("--todo", args.todo), ("--json", args.json), ("--answer-key", args.answer_key)):
        if given:
            parser.error(f"{option} is for grading one kit; a folder of submissions is compared whole")
    reference = args.reference or (KIT_ROOT if has_solutions(KIT_ROOT) else None)
    if reference is None:
        parser.error("the similarity report reads the blocks by the instructor's kit: pass --reference KIT_DIR")
    out = Path(args.similarity)
    try:
        report = write_report(args.submission, out, blocks.load_layout(reference),
                              skip=[path for path in (args.gradebook, args.feedback, args.roster) if path])
    except (OSError, blocks.SubmissionError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    flagged = sum(pair.flagged for found in report.pairs.values() for pair in found)
    table, page = report_paths(out)
    print(f"similarity: {len(report.texts)} submission(s) compared, {flagged} pair-TODO(s) flagged: {page}, {table}"
          + (f"; {len(report.unread)} not read (listed in the page)" if report.unread else ""))
    if args.gradebook or args.feedback or args.roster or args.assignment:
        return classroom.main(args, parser)
    return 0

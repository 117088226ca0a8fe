"""Write an offering's facts where the kit states them: ``python -m instructor.facts [--check] [KIT]``.

The facts are written once: points per TODO and per check in the TODO table
(``hwlib/machinery/todos.py``), the episode cap, the convergence deadline and the other settings in
``hwlib/settings.py``. This tool derives from them every place that states one in words: the
notebooks' Todo headings ("(10 pts)") and rubric tables, the points table of ``docs/grading.md``, the
totals in the README and docs, the settings' tables (``settings.py``, ``policy_search.py``), the
known mistakes' diagnoses (``instructor/wrong_solutions/``) and the prose anywhere in the README,
``docs/``, ``hwlib/``, ``hwtools/`` and ``instructor/`` that names the episode cap or the deadline.
Notebooks' stored outputs are not touched: when a fact changes what a cell prints, re-store the
notebook executed (docs/development.md).

``--check`` changes nothing and exits 1, listing each problem, where a file is not what the facts
give, where the episode cap or the automatic points' total is written as a literal that no fact
derives (in code and templates: ``literals``), or where the points table disagrees with
itself or with the grader's checks (a check renamed in one of them: ``table_problems``). The
release tools and the class run refuse to start on any of these (``instructor/gate.py``).
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import re
import sys
from pathlib import Path
from types import SimpleNamespace

from hwtools import facts as fact_files
from instructor.kit import kit_files

KIT = fact_files.KIT
NOTEBOOKS = ("notebooks/p1_cartpole_finite_difference.ipynb", "notebooks/p2_food_cutting_logistic_regression.ipynb")
WRITTEN = ("README.md", "docs/", "hwlib/", "hwtools/", "instructor/")  # where the texts it writes live
SUFFIXES = (".md", ".py", ".j2", ".txt")
# Where a literal cap or total is looked for: the kit's code and templates (a notebook's code cells, the known
# mistakes' words), but not the tests (they read the offering; the variant run in tests/instructor/test_variant.py
# proves it); prose is tests/instructor/test_facts.py's.
CODE = (".py", ".j2", ".sh", ".toml", ".txt", ".ipynb")
UNSCANNED = ("tests/",)
THE_ONE_PLACE = (str(fact_files.SETTINGS), re.compile(r"^[A-Z][A-Z0-9_]* = "))  # the settings themselves
CAP_WORDS = r"\b(?:step\w*|rewards?|episodes?|cap|converge\w*|maximum|balanc\w*)\b"  # a line about the cap
SHIFT = 100_003  # moves every number of the facts to one no text states by chance
NUMBER = r"\d+(?:\.\d+)?"


def texts(kit):
    """The kit's files this tool writes facts into: its notebooks and every text file of ``WRITTEN``."""
    names = kit_files(kit)
    return [name for name in NOTEBOOKS if name in names] + \
        [name for name in names if name.startswith(WRITTEN) and name.endswith(SUFFIXES)]


def number(value):
    """``value`` as the docs write it: 2, 1.5."""
    return f"{value:g}"


class Facts:
    """The facts of the kit at ``kit``: its TODO table and its settings."""

    def __init__(self, kit):
        self.table = fact_files.load(kit, fact_files.TABLE)
        self.settings = fact_files.load(kit, fact_files.SETTINGS)
        self.todos = {todo.id: todo for todo in self.table.TODOS}
        self.auto, self.manual = self.table.AUTO_POINTS, self.table.MANUAL_POINTS
        self.cap, self.deadline = self.settings.MAX_EPISODE_STEPS, self.settings.CONVERGENCE_DEADLINE

    def shifted(self):
        """These facts with every number (each setting, each TODO's and each check's points, the
        totals) moved by ``SHIFT``: a number that stays when this tool writes them is derived from none."""
        def move(value):
            return value + SHIFT if isinstance(value, (int, float)) and not isinstance(value, bool) else value

        other = copy.copy(self)
        other.settings = SimpleNamespace(**{name: move(value) for name, value in vars(self.settings).items()})
        other.todos = {todo.id: dataclasses.replace(todo, auto=move(todo.auto), manual=move(todo.manual),
                                                    checks=tuple((key, move(points)) for key, points in todo.checks))
                       for todo in self.todos.values()}
        other.auto, other.manual = move(self.auto), move(self.manual)
        other.cap, other.deadline = move(self.cap), move(self.deadline)
        return other

    def total(self, todo):
        return self.todos[todo].auto + self.todos[todo].manual

    def graded(self, todo):
        """How a notebook's rubric says who grades ``todo``."""
        info = self.todos[todo]
        if info.auto and info.manual:
            return f"{number(info.auto)} automatically, {number(info.manual)} by hand"
        return "automatically" if info.auto else "by hand"

    def points_cell(self, todo):
        """docs/grading.md's points column."""
        info = self.todos[todo]
        if info.auto and info.manual:
            return f"{number(info.auto)} + {number(info.manual)} by hand"
        return number(info.auto) if info.auto else f"{number(info.manual)} by hand"


def _prose(text, facts):
    """The facts every text may state in words: totals, the episode cap, the deadline."""
    cap, deadline = str(facts.cap), str(facts.deadline)
    rules = [
        (r"(?<![\w/.])(\d+)/\1(?![\w/.])", lambda m: f"{number(facts.auto)}/{number(facts.auto)}"),
        (rf"{NUMBER}( points are automatic, ){NUMBER}( are graded by hand)",
         lambda m: f"{number(facts.auto)}{m[1]}{number(facts.manual)}{m[2]}"),
        (rf"(auto total \(/){NUMBER}(\))", lambda m: f"{m[1]}{number(facts.auto)}{m[2]}"),
        (rf"(?<![\w.]){NUMBER}( points in all| manual points)", lambda m: f"{number(facts.manual)}{m[1]}"),
        (rf"(`(\d\.\d\.\d) by hand: [^`(]*\(/){NUMBER}(\)`)", lambda m: f"{m[1]}{number(facts.todos[m[2]].manual)}{m[3]}"),
        (r"(converges? within |stay within |climbing after )\d+( iterations)", lambda m: f"{m[1]}{deadline}{m[2]}"),
        (r"(above 99% within )\d+( iterations)", lambda m: f"{m[1]}{facts.settings.TARGET_ITERATIONS}{m[2]}"),
    ]
    for before, after in [("or ", " steps pass"), (r"total reward is \*\*", r"\*\*"), ("all ", " steps"),
                          ("maximum of ", ""), ("percentage at ", ""), ("balance for all ", ""), ("often all ", " but"),
                          ("for instance ", " on every one"), ("policies at ", ""), ("reaches ", " within"),
                          ("reaches ", " and falls"), ("reached ", " to stay"), ("settles at reward ", ""),
                          (r"``settings.MAX_EPISODE_STEPS`` \(", r"\)")]:
        rules.append((rf"(?<![\w.])({before})\d+({after})(?!\d)", lambda m: f"{m[1]}{cap}{m[2]}"))
    settings = facts.settings
    grid, episodes = settings.LANDSCAPE_GRID_SIZE, settings.LANDSCAPE_NUM_EPISODES
    for value, contexts in [
        (settings.NUM_RANDOM_POLICIES, [("Draw ", " parameter vectors"), ("histogram of the ", " rewards"),
                                        ("histogram of ", " rewards"), ("the ", r"\s+random policies"),
                                        ('Todo\\("1\\.1\\.3", "', " random policies")]),
        (settings.NUM_ROLLOUTS, [(r"scored on the \*same\* ", " start states"), (r"\*\*", r" episodes per evaluation\."),
                                 ("each iteration on ", " fresh episodes")]),
        (settings.FD_STEP, [(r"step, \$h = ", r"\$"), (r"uses \$h = ", r"\$")]),
        (episodes, [(r"\], ", " episodes, seed"), ("mean reward of ", " episodes"), (r"plays the \*same\* ", " start states"), ("on ", " fixed ones")]),
        (grid, [("The ", " × "), ("× ", " cells"), (r"\), ", " x "), ("x ", r" over \[")]),
        (f"{grid * grid * episodes:,}", [(r"\(", r" episodes\)"), ("Each redraw plays ", " episodes")]),
    ]:
        for before, after in contexts:
            edge = r"(?<![\w.,])" if before[:1].isalpha() else ""  # "the 1000", not "othe 1000"
            rules.append((rf"{edge}({before})\d[\d,]*(?:\.\d+)?({after})", lambda m, value=value: f"{m[1]}{value:g}{m[2]}"
                          if isinstance(value, (int, float)) else f"{m[1]}{value}{m[2]}"))
    for pattern, make in rules:
        text = re.sub(pattern, make, text)
    return text


def _headings_and_rubrics(text, facts):
    """A notebook's Todo headings, rubric headings and rubric rows."""
    def heading(m):
        total = facts.total(m[2])
        return f"{m[1]}({number(total)} pt{'' if total == 1 else 's'})"

    def rubric_total(m):
        return f"{m[1]}{number(sum(facts.total(todo) for todo in facts.todos if todo.startswith(m[2] + '.')))}{m[3]}"

    def row(m):
        return f"| {m[1]} {m[2]}| {number(facts.total(m[1]))} | {facts.graded(m[1])} |"

    text = re.sub(rf"^(#+ (\d\.\d\.\d) Todo: .*)\({NUMBER} pts?\)", heading, text, flags=re.M)
    text = re.sub(rf"^(## Rubric \(problem (\d), ){NUMBER}( points\))", rubric_total, text, flags=re.M)
    return re.sub(rf"^\| (\d\.\d\.\d) ([^|]*)\| {NUMBER} \| (?:automatically|by hand|{NUMBER} automatically, {NUMBER} by hand) \|",
                  lambda m: row(m) if m[1] in facts.todos else m[0], text, flags=re.M)


def _grading_table(text, facts):
    """docs/grading.md's table: each TODO's points, and each check's points in the order of ``Todo.checks``."""
    def row(m):
        todo = facts.todos[m[1]]
        points = iter([number(points) for _, points in todo.checks if points])
        parts = re.split(rf"((?:^|; ){NUMBER}(?: by hand)?: )", m[4])
        said = [part for part in parts if re.fullmatch(rf"(?:; )?{NUMBER}: ", part or "")]
        if len(said) != len([p for _, p in todo.checks if p]):
            return m[0]  # the row does not list each check's points: left as it is
        out = []
        for part in parts:
            if re.fullmatch(rf"(?:; )?{NUMBER}: ", part or ""):
                part = re.sub(NUMBER, next(points), part, count=1)
            elif re.fullmatch(rf"(?:; )?{NUMBER} by hand: ", part or ""):
                part = re.sub(NUMBER, number(todo.manual), part, count=1)
            out.append(part)
        return f"| {m[1]} {m[2]}| {facts.points_cell(m[1])} | {''.join(out)}|"

    return re.sub(rf"^\| (\d\.\d\.\d) ([^|]*)\| ({NUMBER}(?: \+ {NUMBER})?(?: by hand)?) \| ([^|]*)\|",
                  lambda m: row(m) if m[1] in facts.todos else m[0], text, flags=re.M)


def _settings_table(text, facts):
    """The value column of a docstring table of settings, for the settings that are one number."""
    def row(m):
        value = getattr(facts.settings, m[2], None)
        if m[2] == "LEARNING_RATE" or isinstance(value, bool) or not isinstance(value, (int, float)):
            return m[0]
        return f"{m[1]}{str(value).ljust(len(m[3]) - 1)} |"

    return re.sub(r"^(\| ``(\w+)`` +\| )([^|]+)\|", row, text, flags=re.M)


def rewrite(relative, text, facts):
    """``text`` of the file ``relative`` with the facts written in."""
    if relative.endswith(".ipynb"):
        notebook = json.loads(text)
        for cell in notebook["cells"]:
            if cell["cell_type"] == "markdown":
                source = "".join(cell["source"])
                new = _prose(_headings_and_rubrics(source, facts), facts)
                if new != source:
                    cell["source"] = new.splitlines(keepends=True)
        return json.dumps(notebook, indent=1, sort_keys=True, ensure_ascii=False) + "\n"
    if relative == "docs/grading.md":
        text = _grading_table(text, facts)
    if relative in ("hwlib/settings.py", "hwlib/policy_search.py"):
        text = _settings_table(text, facts)
    return _prose(text, facts)


def run(kit=KIT, check=False):
    """Rewrite (or, with ``check``, only compare) every file; returns the files that differed."""
    kit, facts, changed = Path(kit), Facts(kit), []
    for relative in texts(kit):
        path = kit / relative
        text = path.read_text(encoding="utf-8")
        new = rewrite(relative, text, facts)
        if new != text:
            changed.append(relative)
            if not check:
                path.write_text(new, encoding="utf-8")
    return changed


def _scanned_lines(kit, relative, facts):
    """(where, line as ``facts`` would write it, line as it is) of a kit file: a notebook's code cells
    (not its prose, nor its outputs, which a run writes), any other file's lines."""
    text = (kit / relative).read_text(encoding="utf-8")
    written = rewrite(relative, text, facts) if relative in NOTEBOOKS or relative.startswith(WRITTEN) and \
        relative.endswith(SUFFIXES) else text
    if relative.endswith(".ipynb"):
        for number, (cell, was) in enumerate(zip(json.loads(written)["cells"], json.loads(text)["cells"]), start=1):
            if cell["cell_type"] == "code":
                yield from ((f"{relative}, cell {number}", *lines) for lines in
                            zip("".join(cell["source"]).splitlines(), "".join(was["source"]).splitlines()))
        return
    for number, lines in enumerate(zip(written.splitlines(), text.splitlines()), start=1):
        yield (f"{relative}:{number}", *lines)


def literals(kit=KIT):
    """Where the kit's code and templates (``CODE``, but ``UNSCANNED``) write the episode cap or the
    automatic points' total as a literal: its number where it stays when every fact changes (the file
    read as this tool would write it with ``Facts.shifted``). Code reads them
    (``settings.MAX_EPISODE_STEPS``, ``AUTO_POINTS``); words get them from a rule above."""
    kit, facts = Path(kit), Facts(kit)
    other = facts.shifted()
    cap, auto = re.escape(number(facts.cap)), re.escape(number(facts.auto))
    wanted = [("the episode cap", number(facts.cap), "settings.MAX_EPISODE_STEPS",  # on a line about episodes
               rf"(?<![\w.,-]){cap}(?![\w,]|\.\d)(?=.*?{CAP_WORDS})|{CAP_WORDS}.*?(?<![\w.,-]){cap}(?![\w,]|\.\d)"),
              ("the automatic points' total", number(facts.auto), "AUTO_POINTS of hwlib/machinery/todos.py",
               rf"(?<![\w.,-]){auto}(?:/{auto})?\s*(?:points?|pts)\b|/{auto}\b|(?<![\w.])\b{auto}/|"
               rf"\b(?:score|total|earn\w*)\W{{1,15}}{auto}\b|[=!<>]=\s*{auto}\b|\w*(?:point|total|score)\w*\s*=\s*{auto}\b")]
    found = []
    for relative in kit_files(kit):
        if relative.startswith(UNSCANNED) or not relative.endswith(CODE) or \
                not any(value in (kit / relative).read_text(encoding="utf-8") for _, value, _, _ in wanted):
            continue
        for where, line, was in _scanned_lines(kit, relative, other):
            if relative == THE_ONE_PLACE[0] and THE_ONE_PLACE[1].match(line):
                continue
            for what, value, name, pattern in wanted:
                if value in line and re.search(pattern, line, flags=re.I):
                    found.append(f"{where}: {what} {value} written as a literal ({was.strip()[:80]!r}): code reads "
                                 f"{name}; prose gets it from a rule of instructor/facts.py")
    return found


def table_problems(kit=KIT):
    """What makes the kit's points table disagree with itself or with the grader's checks (a check
    renamed or missing in one of them, points that do not add up, a hidden behaviour without a
    visible twin): ``hwtools.grade.checks.points_table_problems``, the grader's own refusal."""
    from hwtools.grade import checks  # noqa: PLC0415 - numpy, only for the check
    from hwtools.grade.grader import load_hidden_checks  # noqa: PLC0415

    kit = Path(kit)
    hidden = load_hidden_checks(kit)
    cases = {todo: checks.case_set(todo, hidden) for todo in checks.GRADED_TODOS}
    return checks.points_table_problems(cases, Facts(kit).table.TODOS)


def problems(kit=KIT):
    """Everything ``--check`` reports, in words: stale files, literals, the points table."""
    stale = [f"{relative}: out of date (python -m instructor.facts writes it)" for relative in run(kit, check=True)]
    return stale + literals(kit) + [f"points table: {problem}" for problem in table_problems(kit)]


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m instructor.facts", description=__doc__.split("\n\n")[0])
    parser.add_argument("kit", nargs="?", default=str(KIT), help="the kit's folder (default: this kit)")
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 where a file disagrees with the facts, a cap or total is a literal, "
                             "or the points table disagrees with itself or the grader's checks")
    args = parser.parse_args(argv)
    if not args.check:
        for relative in run(args.kit):
            print(f"rewrote: {relative}")
    found = problems(args.kit)
    for problem in found:
        print(problem)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())

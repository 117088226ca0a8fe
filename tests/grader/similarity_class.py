"""A synthetic class for the similarity report (``hwtools/grade/instructor/similarity.py``): students
who each write every TODO in a way of their own, and planted copies.

An independent student starts each TODO from one of the ways students write it (the kit's natural
solutions, ``natural_solutions/``, and the reference's block) and makes it their own as students do,
each choice drawn at random (``own_version``): operands of + and * in either order, 2 or 2.0, ``a @ b``
or ``np.dot(a, b)``, ``x = x + e`` or ``x += e``, a sub-expression first put in a variable of its own,
a check or a conversion of an input of their habit, their own names and comments. A copier takes
another student's whole ``hwlib/`` and disguises every block one way (``COPY_KINDS``): renamed
variables, reordered lines (two adjacent statements that do not depend on each other swapped),
added comments, or one changed constant. 1.3.3 is one constant (the learning rate, each student's
own pick from the range that converges), copied as it is.

Where one of a planted pair's blocks is nothing but the handout's equations (``handout_only``), the
two share nothing of their own there: that TODO cannot show the copy, and ``recall`` does not count
it (docs/instructor.md, Similarity, says why).
"""

from __future__ import annotations

import ast
import random
import re
from pathlib import Path

from copydetect.utils import filter_code

from hwtools.grade import blocks, kits
from hwtools.grade.instructor import similarity

NATURAL = Path(__file__).resolve().parent / "natural_solutions"
COPY_KINDS = ("renamed", "reordered", "commented", "constant")
NAMES = ("tmp", "val", "res", "acc", "out", "part", "term", "step_vec", "buf", "cur", "delta", "grad_i", "q", "s",
         "num", "den", "probs", "lbl", "scores", "e_i", "work", "total_r", "w_new", "pert", "mine", "result2")
COMMENTS = ("# compute it", "# from the handout", "# TODO check this", "# vectorised", "# per equation",
            "# careful with shapes", "# this works", "# update", "# following the notes", "# sum it up")
HABITS = ("assert np.all(np.isfinite({name}))", "{name} = np.asarray({name})", "assert {name} is not None",
          "{name} = np.array({name}, dtype=float)", "assert len({name}) > 0", "_ = np.shape({name})")


def ways(layout):
    """{todo: [block text]}: the ways students write each TODO (one block per TODO)."""
    found = {}
    for todo, bodies in layout.reference_bodies().items():
        if len(bodies) == 1:
            lines = [line for line in blocks.reindent(bodies[0], "") if not line.lstrip().startswith("###")]
            found[todo] = ["\n".join(lines)]
    for path in sorted(NATURAL.glob("*.py")):
        todo = path.name.split("_")[0]
        if todo in found and not path.stem.endswith("_crlf"):
            found[todo].append(path.read_text(encoding="utf-8"))
    return found


def _parse(text):
    tree = ast.parse("def _block():\n" + "\n".join("    " + line for line in text.splitlines()))
    return tree.body[0].body


def _unparse(statements):
    return "\n".join(ast.unparse(statement) for statement in statements)


def _stored(statements):
    names = []
    for node in ast.walk(ast.Module(body=statements, type_ignores=[])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store) and node.id not in names:
            names.append(node.id)
    return names


def _read_first(statements):
    """The names the block reads before it assigns them (its inputs), in order."""
    first = {}
    nodes = [node for node in ast.walk(ast.Module(body=statements, type_ignores=[])) if isinstance(node, ast.Name)]
    for node in sorted(nodes, key=lambda node: (node.lineno, node.col_offset)):
        first.setdefault(node.id, isinstance(node.ctx, ast.Load))
    return [name for name, loaded in first.items()
            if loaded and name not in ("np", "self", "range", "len", "int", "float", "sigmoid")]


class _OwnStyle(ast.NodeTransformer):
    def __init__(self, rng):
        self.rng = rng

    def visit_BinOp(self, node):
        self.generic_visit(node)
        if isinstance(node.op, (ast.Add, ast.Mult)) and self.rng.random() < 0.5:
            node.left, node.right = node.right, node.left
        if isinstance(node.op, ast.MatMult) and self.rng.random() < 0.5:
            return ast.Call(ast.Attribute(ast.Name("np", ast.Load()), "dot", ast.Load()), [node.left, node.right], [])
        return node

    def visit_Call(self, node):
        self.generic_visit(node)
        function = node.func
        if (isinstance(function, ast.Attribute) and function.attr == "dot" and isinstance(function.value, ast.Name)
                and function.value.id == "np" and len(node.args) == 2 and self.rng.random() < 0.5):
            return ast.BinOp(node.args[0], ast.MatMult(), node.args[1])
        return node

    def visit_Constant(self, node):
        if type(node.value) in (int, float) and float(node.value).is_integer() and self.rng.random() < 0.5:
            node.value = float(node.value) if isinstance(node.value, int) else int(node.value)
        return node

    def visit_Assign(self, node):
        self.generic_visit(node)
        target = node.targets[0] if len(node.targets) == 1 else None
        value = node.value
        if (isinstance(target, ast.Name) and isinstance(value, ast.BinOp) and isinstance(value.op, (ast.Add, ast.Sub))
                and isinstance(value.left, ast.Name) and value.left.id == target.id and self.rng.random() < 0.5):
            return ast.AugAssign(ast.Name(target.id, ast.Store()), value.op, value.right)
        return node


def _hoist(statements, rng, name):
    """A sub-expression of one statement put first in a variable ``name`` of its own."""
    spots = []
    for index, statement in enumerate(statements):
        if isinstance(statement, (ast.Assign, ast.AugAssign, ast.Return, ast.Expr)) and statement.value is not None:
            spots += [(index, node) for node in ast.walk(statement.value)
                      if isinstance(node, (ast.BinOp, ast.Call)) and node is not statement.value
                      and not any(isinstance(inner, ast.Name) and inner.id in ("i", "k", "p", "c") for inner in ast.walk(node))]
    if not spots:
        return statements
    index, node = rng.choice(spots)
    hoisted = ast.Assign([ast.Name(name, ast.Store())], node, lineno=0)
    holder = statements[index]
    for parent in ast.walk(holder):
        for field_name, value in ast.iter_fields(parent):
            if value is node:
                setattr(parent, field_name, ast.Name(name, ast.Load()))
            elif isinstance(value, list) and node in value:
                value[value.index(node)] = ast.Name(name, ast.Load())
    return statements[:index] + [hoisted] + statements[index:]


def _rename(text, rng, names):
    """``text`` with each local name in ``names`` renamed, consistently (whole words)."""
    pool = [name for name in NAMES if name not in text]
    rng.shuffle(pool)
    mapping = {name: pool.pop() for name in names if pool}
    return re.sub(r"\b[A-Za-z_]\w*\b", lambda match: mapping.get(match.group(), match.group()), text)


def _comment(text, rng, count):
    lines = text.splitlines()
    for _ in range(count):
        position = rng.randrange(len(lines) + 1)
        indent = re.match(r"\s*", lines[min(position, len(lines) - 1)]).group()
        lines.insert(position, indent + rng.choice(COMMENTS))
    return "\n".join(lines)


def own_version(way, rng):
    """One student's block, written from ``way`` with their own habits."""
    statements = _OwnStyle(rng).visit(ast.Module(body=_parse(way), type_ignores=[])).body
    for number in range(rng.choice((0, 1, 1, 2))):
        statements = _hoist(statements, rng, f"part{number}")
    statements = _parse(_unparse(statements))  # with the line numbers _read_first orders by
    inputs = _read_first(statements)
    if inputs and rng.random() < 0.6:
        habit = _parse(rng.choice(HABITS).format(name=rng.choice(inputs)))
        statements = (habit + statements) if rng.random() < 0.5 or isinstance(statements[-1], ast.Return) \
            else statements + habit
    text = _rename(_unparse(statements), rng, set(_stored(statements)) - set(inputs))
    return _comment(text, rng, rng.choice((0, 0, 1, 2)))


def _reorder(text, rng):
    """Two adjacent statements that neither read nor write what the other writes, swapped."""
    statements = _parse(text)
    spots = []
    for index in range(len(statements) - 1):
        first, second = statements[index], statements[index + 1]
        if isinstance(second, ast.Return) or isinstance(first, ast.Return):
            continue
        written = [set(_stored([first])), set(_stored([second]))]
        used = [{node.id for node in ast.walk(statement) if isinstance(node, ast.Name)} for statement in (first, second)]
        if not (written[0] & used[1]) and not (written[1] & used[0]):
            spots.append(index)
    if not spots:
        return None
    index = rng.choice(spots)
    statements[index], statements[index + 1] = statements[index + 1], statements[index]
    return _unparse(statements)


def _change_constant(text, rng):
    numbers = list(re.finditer(r"(?<![\w.])\d+(\.\d+)?(e-?\d+)?(?![\w.])", text))
    if not numbers:
        return None
    match = rng.choice(numbers)
    changed = repr(float(match.group()) * 2 + 1)
    return text[:match.start()] + changed + text[match.end():]


def disguised(text, kind, rng):
    """A copier's version of ``text``: one disguise (``COPY_KINDS``); where it does not apply to the
    block (no two independent lines, no constant) the variables are renamed instead."""
    if kind == "reordered":
        text = _reorder(text, rng) or text
    elif kind == "constant":
        text = _change_constant(text, rng) or text
    elif kind == "commented":
        return _comment(text, rng, 3)
    try:
        statements = _parse(text)
        return _rename(text, rng, set(_stored(statements)) - set(_read_first(statements)))
    except SyntaxError:
        return text


def make_class(layout, folder, students, copies, seed):
    """Write ``students`` submissions into ``folder`` (one ``hwlib/`` each), ``copies`` of them copiers
    of another's whole submission. Returns {(original, copier): kind}, the planted pairs."""
    rng = random.Random(seed)
    styles = ways(layout)
    names = [f"s{number:03d}" for number in range(students)]
    bodies = {}
    for student in names:
        bodies[student] = {todo: own_version(rng.choice(found), rng) for todo, found in styles.items()
                           if todo != "1.3.3"}
        bodies[student]["1.3.3"] = f"LEARNING_RATE = {rng.choice((0.0005, 0.0006, 0.00065, 0.0007, 0.0008, 0.001))}"
    planted = {}
    shuffled = names[:]
    rng.shuffle(shuffled)
    for number in range(copies):
        original, copier = shuffled[2 * number], shuffled[2 * number + 1]
        kind = COPY_KINDS[number % len(COPY_KINDS)]
        bodies[copier] = {todo: disguised(text, kind, rng) if todo != "1.3.3" else text
                          for todo, text in bodies[original].items()}
        planted[tuple(sorted((original, copier)))] = kind
    for student in names:
        kits.write_submission(layout, folder / student, bodies[student], others="stub")
    return planted


def natural_class(layout, folder):
    """Each natural solution of a TODO the grader reads as a submission of its own in ``folder`` (every
    other block the stub); a ``_crlf`` file is its twin with Windows line ends, the same solution, so it
    is left out. Returns how many pairs of one TODO's solutions there are."""
    graded = {block.todo for found in layout.blocks_by_file.values() for block in found}
    written = {}
    for path in sorted(NATURAL.glob("*.py")):
        todo = path.name.split("_")[0]
        if todo in graded and not path.stem.endswith("_crlf"):
            kits.write_submission(layout, folder / path.stem, {todo: path.read_text(encoding="utf-8")})
            written[todo] = written.get(todo, 0) + 1
    return sum(count * (count - 1) // 2 for count in written.values())


def _statements(text):
    """A block's statements as copydetect reads them (every name "V"; no comments, no layout), a
    number spelt one way (1.0 as 1)."""
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and type(node.value) is float and node.value.is_integer():
            node.value = int(node.value)
    return {filter_code(ast.unparse(statement), "block.py", "python")[0] for statement in tree.body}


def handout_only(report, planted, layout):
    """{todo: [planted pair]} where one of the two blocks is nothing but the TODO's stub and the
    handout's equations (``similarity.boilerplate_texts``), up to names, comments, layout and how a
    number is spelt: all the two can share there is the handout's."""
    found = {}
    for todo, block in similarity.todo_blocks(layout).items():
        boilerplate = set().union(*map(_statements, similarity.boilerplate_texts(block)))
        found[todo] = [pair for pair in planted if any(
            _statements(report.texts[student].get(todo, "")) <= boilerplate for student in pair)]
    return found


def recall(report, planted, layout, top=10):
    """{todo: share of the planted pairs among that TODO's ``top`` pairs}, of those it can show (not
    ``handout_only``); a TODO where it can show none is left out."""
    found, left_out = {}, handout_only(report, planted, layout)
    for todo, pairs in report.pairs.items():
        best = {pair.students for pair in pairs[:top]}
        counted = [pair for pair in planted if pair not in left_out[todo]]
        if counted:
            found[todo] = sum(pair in best for pair in counted) / len(counted)
    return found

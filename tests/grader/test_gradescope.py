"""The Gradescope bundle, proved without Gradescope: ``python -m instructor.release gradescope OUT.zip``
is unpacked into a temporary folder laid out as ``/autograder`` (a fresh one per submission, as
Gradescope gives a fresh container), ``run_autograder`` runs with this venv's Python (setup.sh is
not run), and each ``results.json`` is checked against a schema written from
``../shared/grading/gradescope-autograder.md`` and against the expected scores.

Two containers (``containers.py``): this machine, where bubblewrap works, and Docker's, where a
``bwrap`` that fails as Docker's seccomp profile makes it fail comes first on PATH, so that the
grader falls back to a user of its own per run. A correct submission is graded in both; the attacks
that got through the old fallback (``tests/grader/cheats/gradescope/``: the results.json overwrite, /tmp
kit borrowing, a relay through /tmp, root) run in Docker's, where they did (test_grading's cheats
attack bubblewrap's sandbox).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

import jsonschema
import pytest

from hwtools.grade import AUTO_POINTS, TODOS, TODO_BY_ID, blocks, judging, kits
from hwtools.grade.grader import is_secret, read_answer_key
from hwtools.grade.instructor.gradescope_autograder import BUNDLE_MARKER

import containers
import editions
import test_grading as proof  # the grader's proof builds the wrong solutions and cheats
from process_watch import live_processes

KIT = Path(__file__).resolve().parents[2]
ATTACKS = Path(__file__).resolve().parent / "cheats" / "gradescope"

TIME_LIMIT = 20
pytestmark = pytest.mark.timeout(900)

VISIBILITY = ["hidden", "after_due_date", "after_published", "visible"]
OUTPUT_FORMATS = ["text", "html", "simple_format", "md", "ansi"]
# Gradescope's results.json, as the summary in ../shared/grading/gradescope-autograder.md gives it.
RESULTS_SCHEMA = {
    "$schema": "http://json-schema.org/draft-07/schema#",
    "type": "object",
    "anyOf": [{"required": ["score"]}, {"required": ["tests"]}],
    "additionalProperties": False,
    "properties": {
        "score": {"type": "number"},
        "execution_time": {"type": "number", "minimum": 0},
        "output": {"type": "string"},
        "output_format": {"enum": OUTPUT_FORMATS},
        "visibility": {"enum": VISIBILITY},
        "stdout_visibility": {"enum": ["hidden", "visible"]},
        "extra_data": {},
        "tests": {
            "type": "array",
            "items": {
                "type": "object",
                "additionalProperties": False,
                "required": ["name", "score", "max_score"],
                "properties": {
                    "name": {"type": "string", "minLength": 1},
                    "number": {"type": "string"},
                    "score": {"type": "number", "minimum": 0},
                    "max_score": {"type": "number", "minimum": 0},
                    "status": {"enum": ["passed", "failed"]},
                    "output": {"type": "string"},
                    "output_format": {"enum": OUTPUT_FORMATS},
                    "tags": {"type": "array", "items": {"type": "string"}},
                    "visibility": {"enum": VISIBILITY},
                },
            },
        },
        "leaderboard": {
            "type": "array",
            "items": {"type": "object", "required": ["name", "value"],
                      "properties": {"name": {"type": "string"}, "value": {}, "order": {"enum": ["asc", "desc"]}}},
        },
    },
}


def check_results(data):
    """The schema, and what JSON Schema cannot say: each score within [0, max_score], the total the
    sum of the tests, a test whose points depend on hidden inputs never visible before publishing."""
    jsonschema.validate(data, RESULTS_SCHEMA)
    for test in data["tests"]:
        assert 0 <= test["score"] <= test["max_score"], test["name"]
        if test["max_score"] > 0 or "hidden inputs" in test.get("tags", []):
            assert test.get("visibility", data.get("visibility", "visible")) not in ("visible", "after_due_date"), test
    assert data["score"] == pytest.approx(sum(test["score"] for test in data["tests"]))
    assert sum(test["max_score"] for test in data["tests"]) == AUTO_POINTS
    assert data["stdout_visibility"] == "hidden"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("bundle") / "autograder.zip"
    result = subprocess.run([sys.executable, "-m", "instructor.release", "gradescope", str(out)], cwd=KIT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="module")
def layout():
    return blocks.load_layout(KIT)


@pytest.fixture(scope="module")
def docker(tmp_path_factory):
    """The environment of a Docker container where bubblewrap fails: a failing ``bwrap`` first on
    PATH and a Python the fallback's users can run (setup.sh's venv). This clone is hidden from the
    pool's users meanwhile: on Gradescope there is no other copy of the reference than source/."""
    folder, python = containers.user_sandbox_python()
    fake = containers.fake_bwrap_folder(tmp_path_factory.mktemp("docker-bin"))
    with containers.hidden_from_pool(KIT):
        yield {"PATH": f"{fake}:{os.environ['PATH']}", "AUTOGRADER_PYTHON": python}
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture()
def broken(tmp_path_factory):
    """A container where no sandbox works: bubblewrap fails and the fallback's users cannot run the
    Python (setup.sh never ran or failed)."""
    if os.geteuid() != 0:
        pytest.skip("the container's users need the grader to run as root")
    fake = containers.fake_bwrap_folder(tmp_path_factory.mktemp("broken-bin"))
    python = containers.unrunnable_python(tmp_path_factory.mktemp("root-only") / "bin")
    with containers.hidden_from_pool(KIT):
        yield {"PATH": f"{fake}:{os.environ['PATH']}", "AUTOGRADER_PYTHON": str(python)}


@pytest.fixture(params=["bwrap", "docker"])
def container(request):
    """Each container: where bubblewrap works ({}), and Docker's, where it fails."""
    if request.param == "bwrap":
        from hwtools.grade.sandbox import probe_isolation

        works, how = probe_isolation(sys.executable)
        if not works:
            pytest.skip(f"bubblewrap does not work here: {how}")
        return {}
    return request.getfixturevalue("docker")


def autograde(bundle, tmp_path, make_submission, container=None, sandbox=None, metadata=None):
    """Lay out ``tmp_path`` as /autograder (the bundle in source/, run_autograder beside it), put a
    submission in submission/ (and ``metadata`` in submission_metadata.json), run run_autograder (in
    ``container``: environment variables; the ``sandbox`` expected there, default user in a
    container, bwrap here); (results.json, stdout)."""
    root = tmp_path / "autograder"
    (root / "source").mkdir(parents=True)
    (root / "results").mkdir()
    if metadata is not None:
        (root / "submission_metadata.json").write_text(json.dumps(metadata), encoding="utf-8")
        (root / "submission_metadata.json").chmod(0o644)
    with zipfile.ZipFile(bundle) as archive:
        archive.extractall(root / "source")
        for info in archive.infolist():  # zipfile keeps no permission bits: put them back as Gradescope does
            os.chmod(root / "source" / info.filename, (info.external_attr >> 16) & 0o777)
    shutil.copy(root / "source" / "run_autograder", root / "run_autograder")
    (root / "submission").mkdir()
    make_submission(root / "submission")
    env = os.environ | {"AUTOGRADER_ROOT": str(root), "AUTOGRADER_PYTHON": sys.executable,
                        "AUTOGRADER_TIME_LIMIT": str(TIME_LIMIT)} | (container or {})
    result = subprocess.run([str(root / "run_autograder")], cwd=root, env=env, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr + result.stdout
    data = json.loads((root / "results" / "results.json").read_text())
    check_results(data)
    if sandbox == "none":  # no sandbox: nothing ran, and the log and results.json say so
        assert data["extra_data"]["sandbox"] == "none" and "sandbox: none: " in result.stdout, result.stdout
    elif container:  # Docker's: the fallback graded, and the log and results.json say so
        assert data["extra_data"]["sandbox"] == "user" and "sandbox: user: " in result.stdout, result.stdout
        assert "before results.json was written" in result.stdout
    elif container is not None:
        assert data["extra_data"]["sandbox"] == "bwrap" and "sandbox: bwrap: " in result.stdout
    # graded by the bundle's own grader, and the reference deleted from disk once loaded
    assert f"grader: {(root / 'source' / 'hwtools' / 'grade').resolve()}" in result.stdout
    assert not (root / "source" / "hwlib").exists() and not (root / "source" / "instructor").exists()
    return data, result.stdout


def by_name(data):
    return {test["name"]: test for test in data["tests"]}


def points_tests(data):
    return {test["number"][:-2]: test for test in data["tests"] if test["visibility"] == "after_published"}


def visible_tests(data):
    return {test["number"][:-2]: test for test in data["tests"] if test["visibility"] == "visible"}


def test_the_bundle_holds_what_gradescope_runs_and_nothing_a_grader_does_not_need(bundle, tmp_path):
    with zipfile.ZipFile(bundle) as archive:
        infos = {info.filename: info for info in archive.infolist()}
        requirements = archive.read("requirements.txt").decode()
        setup = archive.read("setup.sh").decode()
    names = set(infos)
    assert {"setup.sh", "run_autograder", "requirements.txt", BUNDLE_MARKER, "instructor/hidden_checks/__init__.py",
            "hwlib/finite_diff.py", "hwtools/grade/instructor/gradescope_autograder.py"} <= names
    for name in ("setup.sh", "run_autograder"):
        assert (infos[name].external_attr >> 16) & 0o111, f"{name} is not executable"
    assert not [name for name in names if name.startswith(("notebooks/", "tests/", "benchmarks/", "data/"))
                or name.endswith(".ipynb") or name in ("instructor/release.py", "README.md") or "__pycache__" in name]
    known = {f"instructor/wrong_solutions/{path.name}" for path in proof.WRONG.glob("*.txt")}
    assert known and known <= names  # the known mistakes: Gradescope's feedback names them as the preview does
    assert "BEGIN SOLUTION 1.2.1" in zipfile.ZipFile(bundle).read("hwlib/finite_diff.py").decode()  # the reference
    assert re.search(r"^numpy[<>=]", requirements, re.M) and re.search(r"^gymnasium[<>=]", requirements, re.M)
    assert "python3-venv" in setup and "bubblewrap" in setup and "requirements.txt" in setup
    # every run's filter, bubblewrap's too: without it no submission is graded
    assert re.search(r"^apt-get install .*\bpython3-seccomp\b", setup, re.M), setup
    again = tmp_path / "again.zip"
    subprocess.run([sys.executable, "-m", "instructor.release", "gradescope", str(again)], cwd=KIT, check=True,
                   capture_output=True, timeout=300)
    assert again.read_bytes() == bundle.read_bytes(), "two builds are byte-identical"
    refused = subprocess.run([sys.executable, "-m", "instructor.release", "gradescope", str(again)], cwd=KIT,
                             capture_output=True, text=True, timeout=300)
    assert refused.returncode == 1 and "--force" in refused.stderr


def test_the_bundled_requirements_cover_what_the_graded_code_imports():
    """hwlib, as the worker imports it, needs only numpy, gymnasium and what they depend on."""
    code = "import json, sys; before = set(sys.modules); import hwlib; print(json.dumps(sorted(set(sys.modules) - before)))"
    modules = json.loads(subprocess.run([sys.executable, "-c", code], cwd=KIT, capture_output=True, text=True,
                                        check=True, timeout=120).stdout)
    distributions = importlib.metadata.packages_distributions()
    used = {dist for name in modules if name.split(".")[0] not in sys.stdlib_module_names
            for dist in distributions.get(name.split(".")[0], []) if name.split(".")[0] != "hwlib"}
    from instructor.gradescope_bundle import GRADING_REQUIREMENTS

    allowed, pending = set(), list(GRADING_REQUIREMENTS)
    while pending:
        name = pending.pop()
        if name.lower() in allowed:
            continue
        allowed.add(name.lower())
        for requirement in importlib.metadata.requires(name) or []:
            if "extra ==" not in requirement:
                pending.append(re.match(r"[A-Za-z0-9_.-]+", requirement)[0])
    normal = {dist.lower().replace("_", "-") for dist in used}
    assert normal <= {name.replace("_", "-") for name in allowed}, normal - allowed


def test_a_correct_submission_earns_every_point(bundle, layout, tmp_path, container):
    earlier = {"results": {"extra_data": {"grading": {"submission_id": 7, "files": "other files", "secret": "a" * 32}}}}
    data, stdout = autograde(bundle, tmp_path, lambda folder: kits.write_submission(layout, folder, others="reference"),
                             container, metadata={"id": 7, "previous_submissions": [earlier]})
    assert data["score"] == AUTO_POINTS
    assert all(test["status"] == "passed" for test in data["tests"])
    assert data["extra_data"]["status"] in ("graded", "not isolated")
    assert "Grading your submission" in stdout  # the full report, for the instructor's log
    assert "grader memory limit: " in stdout
    # the grading's secret: stored for the instructor (extra_data), new (other files than the earlier grading's)
    grading = data["extra_data"]["grading"]
    assert is_secret(grading["secret"]) and grading["secret"] != "a" * 32 and grading["submission_id"] == 7
    assert not grading["reused"] and len(grading["files"]) == 64
    shown = json.dumps({key: value for key, value in data.items() if key != "extra_data"}) + stdout
    assert grading["secret"] not in shown
    if os.geteuid() == 0:  # earlier results (and their secrets) out of a pool user's reach before any run
        assert (tmp_path / "autograder" / "submission_metadata.json").stat().st_mode & 0o077 == 0


def test_a_rerun_of_the_same_submission_reuses_its_stored_secret_and_nothing_else_does():
    from hwtools.grade.instructor.gradescope_autograder import stored_secret

    def earlier(submission_id, files, secret):
        return {"results": {"extra_data": {"grading": {"submission_id": submission_id, "files": files, "secret": secret}}}}

    listed = [earlier(6, "f" * 64, "1" * 32), earlier(7, "e" * 64, "2" * 32), earlier(7, "f" * 64, "3" * 32)]
    assert stored_secret({"id": 7, "previous_submissions": listed}, "f" * 64) == "3" * 32  # this submission, its files
    assert stored_secret({"id": 8, "previous_submissions": listed}, "f" * 64) is None  # a resubmission: a new grading
    assert stored_secret({"id": 7, "previous_submissions": listed}, "d" * 64) is None
    assert stored_secret({"id": 7, "previous_submissions": [earlier(7, "f" * 64, "not a secret")]}, "f" * 64) is None
    for broken in ({}, {"id": 7}, {"id": 7, "previous_submissions": [None, {"results": []}, {"results": {}}]}, []):
        assert stored_secret(broken, "f" * 64) is None


def attack(name, layout, answer_key):
    """A submission maker for the attack ``tests/grader/cheats/gradescope/NAME.txt``, and its cheat."""
    cheat = proof.parse_cheat(ATTACKS / f"{name}.txt")
    return (lambda folder: proof.build_cheat(layout, cheat, folder, answer_key)), cheat


@pytest.fixture(scope="module")
def answer_key(tmp_path_factory):
    return read_answer_key(editions.answer_key_file(tmp_path_factory))


def test_a_child_that_rewrites_results_json_after_the_grader_does_not_change_the_score(bundle, layout, tmp_path,
                                                                                      docker, answer_key):
    submission, cheat = attack("results_overwrite", layout, answer_key)
    marker = Path("/tmp/hwgrade-overwrite-" + hashlib.sha256(str(tmp_path / "autograder").encode()).hexdigest()[:12])
    seen, stop = [], threading.Event()
    forger = lambda cmdline: cmdline.startswith(b"sh\0-c\0end=") and str(tmp_path).encode() in cmdline  # noqa: E731

    def watch():  # its forger lives only while the run does (its marker in /tmp is refused: a run makes no file)
        while not stop.is_set() and not seen:
            for pid in filter(str.isdigit, os.listdir("/proc")):
                try:
                    if forger(Path(f"/proc/{pid}/cmdline").read_bytes()):
                        seen.append(True)
                except OSError:
                    pass
            time.sleep(0.01)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        data, _ = autograde(bundle, tmp_path, submission, docker)
        stop.set()
        watcher.join(timeout=10)
        assert data["score"] == cheat["points"] == 0
        assert seen, "the attack did not run"  # without namespaces it finds the root and starts its forger
        assert not marker.exists(), "the run made a file in /tmp"
        time.sleep(1.5)  # the forged writes came every 0.05 s while the child lived
        assert json.loads((tmp_path / "autograder" / "results" / "results.json").read_text()) == data
        assert not live_processes(forger), "the child outlived grading"
    finally:
        marker.unlink(missing_ok=True)
    root = tmp_path / "autograder"  # nothing under the root that runs later is writable by the sandbox's users
    assert (root / "source").stat().st_mode & 0o777 == 0o700
    assert (root / "results").stat().st_uid == 0 and not (root / "results").stat().st_mode & 0o022
    for path in [root / "run_autograder", *(root / "source").rglob("*")]:
        assert path.is_symlink() or not path.lstat().st_mode & 0o022, path


def test_a_submission_cannot_borrow_the_reference_from_another_run_s_kit(bundle, layout, tmp_path, docker,
                                                                        answer_key):
    submission, cheat = attack("tmp_borrowing", layout, answer_key)
    cheat["bodies"]["1.2.1"] = cheat["bodies"]["1.2.1"].replace("THIS_CLONE", str(layout.root))
    data, _ = autograde(bundle, tmp_path, submission, docker)
    assert points_tests(data)["1.2.1"]["score"] == 0 and data["score"] == cheat["points"] == 0


def test_nothing_a_run_leaves_in_a_shared_place_reaches_a_later_run(bundle, layout, tmp_path, docker, answer_key):
    """2.2.1's run tries to leave its inputs (hidden ones too) in world-readable files in /tmp and
    /dev/shm; 2.2.2's run, later, finds nothing to show in its feedback: a run makes no file."""
    submission, cheat = attack("tmp_relay", layout, answer_key)
    relay = f"hwgrade-relay-{proof.CHANNEL}"  # this test run's own (cheats/README.md)
    for place in ("/tmp", "/dev/shm"):
        Path(place, relay).unlink(missing_ok=True)
    try:
        data, _ = autograde(bundle, tmp_path, submission, docker)
    finally:
        left = [place for place in ("/tmp", "/dev/shm") if Path(place, relay).exists()]
        for place in left:
            Path(place, relay).unlink()
    assert "RELAYED" not in json.dumps(data), "a run read what an earlier run left"
    assert data["score"] == cheat["points"] == AUTO_POINTS and not left


def test_student_code_never_runs_as_root(bundle, layout, tmp_path, docker, answer_key):
    submission, cheat = attack("runs_as_root", layout, answer_key)
    data, _ = autograde(bundle, tmp_path, submission, docker)
    assert points_tests(data)["2.2.1"]["score"] == 0 and data["score"] == cheat["points"]


def test_where_no_sandbox_works_no_student_code_runs_and_results_json_says_the_autograder_is_misconfigured(
        bundle, layout, tmp_path, broken, answer_key):
    """Fail closed: the attack that rewrote results.json as root in such a container (every point)
    never runs; the student gets 0 and "misconfigured", the instructor the reason and the fix."""
    submission, _ = attack("results_overwrite", layout, answer_key)
    marker = Path("/tmp/hwgrade-overwrite-" + hashlib.sha256(str(tmp_path / "autograder").encode()).hexdigest()[:12])
    try:
        data, stdout = autograde(bundle, tmp_path, submission, broken, sandbox="none")
        time.sleep(1.5)
        assert json.loads((tmp_path / "autograder" / "results" / "results.json").read_text()) == data
        assert not marker.exists(), "the submission's code ran"
    finally:
        marker.unlink(missing_ok=True)
    assert data["score"] == 0 and all(test["score"] == 0 for test in data["tests"])
    assert "The autograder is misconfigured" in data["output"] and "not your fault" in data["output"]
    assert data["extra_data"]["status"].startswith("not graded: the autograder is misconfigured")
    fix = data["extra_data"]["misconfigured"]
    assert "bubblewrap" in fix and "python -m hwtools.grade.instructor.user_sandbox create" in fix
    assert "setup.sh" in stdout and "Grading your submission" not in stdout


def test_a_wrong_solution_loses_its_own_todo_and_is_told_what_to_fix(bundle, layout, tmp_path):
    todo, _, bodies = proof.parse_wrong_solution(proof.WRONG / "forward_difference.txt")

    def bare_files(folder):  # Gradescope's upload of single files: the library's files without hwlib/
        kits.write_submission(layout, folder / "kit", {todo: bodies}, others="reference")
        for path in (folder / "kit" / "hwlib").glob("*.py"):
            shutil.move(path, folder / path.name)
        shutil.rmtree(folder / "kit")

    data, _ = autograde(bundle, tmp_path, bare_files)
    assert data["score"] == AUTO_POINTS - TODO_BY_ID[todo].auto
    points, visible = points_tests(data), visible_tests(data)
    assert points[todo]["score"] == 0 and points[todo]["status"] == "failed"
    assert all(test["score"] == test["max_score"] for other, test in points.items() if other != todo)
    assert visible[todo]["status"] == "failed" and visible[todo]["max_score"] == 0
    for word in ("First failing check", "input:", "expected:", "actual:"):
        assert word in visible[todo]["output"]
    # The known mistake is named, as in the preview and the class's feedback (the bundle carries them).
    assert proof.mistakes.read_wrong_solution(proof.WRONG / "forward_difference.txt").diagnosis in visible[todo]["output"]
    assert "read as hwlib/" in data["output"]


def test_a_cheat_earns_nothing_and_the_visible_feedback_says_nothing_of_hidden_inputs(bundle, layout, tmp_path,
                                                                                     tmp_path_factory):
    key_path = editions.answer_key_file(tmp_path_factory)
    cheat = proof.parse_cheat(proof.CHEATS / "hardcoded_visible.txt")

    def nested(folder):  # the kit one folder down, as a zip of the kit's folder unpacks
        proof.build_cheat(layout, cheat, folder / "hw1", read_answer_key(key_path))

    data, _ = autograde(bundle, tmp_path, nested)
    assert data["score"] == 0
    points, visible = points_tests(data), visible_tests(data)
    for todo in cheat["hardcode"]:
        # right on every visible input: the visible test passes and says nothing more;
        # the points, decided by the hidden inputs too, wait for the grades to be published
        assert visible[todo]["status"] == "passed", visible[todo]
        assert "hidden" not in visible[todo]["output"]
        assert points[todo]["score"] == 0 and "on a hidden input" in points[todo]["output"]
        assert points[todo]["visibility"] == "after_published"


def test_an_unreadable_submission_gets_zero_and_the_reason_at_once(bundle, tmp_path):
    def traversal(folder):
        with zipfile.ZipFile(folder / "upload.zip", "w") as archive:
            archive.writestr("../../../autograder/results/results.json", "{}")
            archive.writestr("hwlib/finite_diff.py", "x = 1\n")

    data, _ = autograde(bundle, tmp_path, traversal)
    assert data["score"] == 0 and data["extra_data"]["status"].startswith("rejected: a path that leaves")
    assert "rejected: a path that leaves" in data["output"] and "submit again" in data["output"]
    assert [test["number"] for test in data["tests"]] == [todo.id for todo in TODOS if todo.auto]


def test_students_read_their_status_without_the_sandbox_s_state():
    from hwtools.grade.instructor.gradescope_autograder import results_json

    stopped = judging.judge_todo("2.2.1", None, {}, None, None, str, (5, 1024), [])
    stopped.update(status="time limit", visible_status="time limit")  # stopped in its visible run
    result = {"notes": [], "total": {"auto_earned": 0.0}, "isolated": False, "isolation": "bwrap is missing",
              "todos": [stopped]}
    data = results_json(result, "timed out: 2.2.1; not isolated")
    assert "Status: **timed out: 2.2.1**" in data["output"] and "isolated" not in data["output"]
    assert data["extra_data"] == {"status": "timed out: 2.2.1; not isolated", "isolated": False,
                                  "isolation": "bwrap is missing", "sandbox": "", "seconds": 0.0, "grading": {}}
    stopped["visible_status"] = "graded"  # stopped in its hidden phase: shown after publication only
    assert results_json(result, "timed out: 2.2.1; not isolated")["output"].startswith("Status: **graded**")
    result["todos"] = []
    check_results(results_json(result, "graded"))
    assert results_json(result, "graded", sandbox="user")["extra_data"]["sandbox"] == "user"
    assert results_json(result, "not isolated")["output"].startswith("Status: **graded**")

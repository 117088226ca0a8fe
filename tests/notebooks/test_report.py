"""``python -m hwtools.report OUT_DIR``: the report takes every number from the executed notebooks, and a grader
can grade it (page numbers, a name line, the 2.1.1 derivation typeset, figures that fill the page and say what
they show, pages that read offline).

The first part needs no notebook run. The second runs the command once, in a student edition (module fixture,
about a minute: it executes both notebooks) and reads what it wrote: the PDF through poppler's ``pdftotext``
and ``pdftoppm``.
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import nbformat
import numpy as np
import pytest

from hwlib import settings
from hwlib.cartpole import CartPoleLinearPolicy, run_policy
from hwlib.plots.training import PRINT_WIDTH
import foreign_os
from day_one import find_python, kit_env, student_python, versions_tested
from hwtools import report
from hwtools.report import chromium, words
from reports import DERIVATION, TOP, assert_printed_as_on_linux, linux_check_texts, output_text, p1_values, p2_values

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPORT_TIMEOUT = 900  # seconds; the run takes about a minute on 2 cores
# The first test that reads the report also waits for its module fixture: an edition, a student's Python (the first
# time on a machine, its packages: ``day_one.packages_of``) and the report itself.
pytestmark = pytest.mark.timeout(REPORT_TIMEOUT + 600)
STUDENT_NAME = "Ada Lovelace / alovelac"


# --- part 1: the pieces, without running the notebooks ---------------------------------------------


def test_the_export_cell_runs_on_its_own_and_writes_json(tmp_path):
    """The extra cell needs nothing but the kernel's namespace; it writes plain JSON and cleans up after itself."""
    wanted = {"tried": (), "run": ("rewards", "policy.params"), "rate": (), "where": (), "missing": (), "opaque": (),
              "short": ("nope",)}
    namespace = {
        "tried": {"mine": (0.1, -0.2, np.float32(-1.0), -0.3)},
        "run": SimpleNamespace(rewards=np.array([9.5, TOP]), policy=SimpleNamespace(params=np.zeros(4))),
        "rate": np.float64(7e-4),
        "where": Path("/data/data.npz"),
        "opaque": object(),
        "short": 3,
    }
    exec(compile(report.export_cell_source(wanted, tmp_path / "values.json"), "<extra cell>", "exec"), namespace)
    exported = json.loads((tmp_path / "values.json").read_text())
    assert exported["values"] == {
        "tried": {"mine": [0.1, -0.2, -1.0, -0.3]},
        "run": {"rewards": [9.5, TOP], "policy.params": [0.0, 0.0, 0.0, 0.0]},
        "rate": 7e-4,
        "where": "/data/data.npz",
    }
    assert exported["problems"] == [
        "`missing` is not defined",
        "`opaque` holds a object, which the report cannot read",
        "`short` has no attribute `short.nope` (it is a int)",
    ]
    assert "_report_export_variables" not in namespace


def test_a_missing_variable_is_named_with_where_it_is_made(tmp_path):
    path = tmp_path / "values.json"
    path.write_text(json.dumps({"values": {}, "problems": ["`tried` is not defined"]}))
    with pytest.raises(report.ReportError, match=r"(?s)p1\.ipynb: .*`tried` is not defined \(made in TODO 1\.1\.2"):
        report.read_exported(path, "p1.ipynb")


def test_bad_notebook_values_are_refused_naming_the_variable():
    with pytest.raises(report.ReportError, match=r"`tried\['x'\]` must be 4 values.*TODO 1\.1\.2"):
        report.problem_one(p1_values(tried={"x": [1, 2, 3]}))
    with pytest.raises(report.ReportError, match=r"`tried` must be a non-empty dict"):
        report.problem_one(p1_values(tried=[0, 0, 0, 0]))
    with pytest.raises(report.ReportError, match=r"`learning_rate` must be a number"):
        report.problem_one(p1_values(learning_rate=None))
    with pytest.raises(report.ReportError, match=r"`run.rewards` must hold finite numbers"):
        report.problem_one(p1_values(run={"rewards": [1.0, float("nan")], "policy.params": [0, 0, 0, 0]}))
    values = p2_values()
    values["test_predictions"] = [0, 1, 5, 0]
    with pytest.raises(report.ReportError, match=r"`test_predictions` must hold class indices 0\.\.1"):
        report.problem_two(values, "derivation")


@pytest.mark.offering
def test_the_answers_show_the_students_parameters_and_the_notebooks_numbers():
    p1 = report.problem_one(p1_values())
    p2 = report.problem_two(p2_values(), DERIVATION)
    answers = report.compute_answers(p1, p2)
    text = report.answers_markdown(answers)
    for name, params in (("my first guess", (0.1, -0.2, -1.0, -0.3)), ("pole angle only", (0, 0, -1, 0))):
        rewards = [int(run_policy(CartPoleLinearPolicy(params), seed=seed)) for seed in settings.HAND_TUNING_SEEDS]
        row = f"| {name} | {report.tried_params_text(params)} | "
        assert row in text and text.split(row)[1].split("\n")[0].endswith(f"| {', '.join(map(str, rewards))} |")
    assert "hand-tuned" not in text
    assert report.rewards_text([9.4, 136.25, 500]) == "9.4, 136.2, 500.0"
    assert f"- reward per iteration: {report.rewards_text(p1.training_rewards)}" in text
    assert "- final parameters: **[0.008, -0.587, 0.886, -1.000]**" in text
    assert f"- converged ({settings.MAX_EPISODE_STEPS} from then on) at iteration: **2** (deadline {settings.CONVERGENCE_DEADLINE}: met)" in text
    assert f"- 1 of 4 random policies reached the maximum reward of {settings.MAX_EPISODE_STEPS}: **25.0%**" in text
    latex, _ = report.answers_latex(answers)  # the same facts in the LaTeX the student edits (the episode cap)
    assert f"reached the maximum reward of {settings.MAX_EPISODE_STEPS}:" in latex
    assert f"converged ({{{settings.MAX_EPISODE_STEPS}}} from then on)" in latex
    assert "| converged | 0% | 95% |" in text
    assert "- test accuracy: **0.750**" in text and "- first iteration with train accuracy above 99%: **2**" in text
    assert "$$\\nabla l = X^\\top (y - p)$$" in text
    assert f"**{report.NAME_LABEL}** {report.NAME_BLANK}" in text
    assert f"**{report.NAME_LABEL}** Ada &amp; Bob" in report.answers_markdown(answers, "Ada & Bob")
    figures = report.make_figures(p1, p2)
    assert sorted(figures) == sorted(report.FIGURES)
    assert figures["p2_confusion_matrix.png"].get_suptitle().startswith("data: synthetic stand-in")


def _notebook(*cells):
    return nbformat.v4.new_notebook(cells=[
        nbformat.v4.new_code_cell(source[5:]) if source.startswith("code:") else nbformat.v4.new_markdown_cell(source)
        for source in cells
    ])


def test_the_derivation_is_the_markdown_under_the_2_1_1_heading():
    notebook = _notebook(
        "# Problem 2",
        # The markers as the student edition has them (the release tool turns the instructor's into these).
        "The objective.\n\n### 2.1.1 The gradient\n<!-- BEGIN TODO 2.1.1 -->\nStep 1: $a$\n#### a detail\n<!-- END TODO 2.1.1 -->",
        "More: $$b$$",
        "### Checking the gradient",
        "not this",
    )
    assert report.derivation_markdown(notebook) == "Step 1: $a$\n#### a detail\n\nMore: $$b$$"
    assert report.derivation_markdown(_notebook("## 2.1.1 Gradient", "my answer", "code:x = 1", "after")) == "my answer"
    assert report.derivation_markdown(_notebook("### 2.1.10 Not it", "text")) is None
    assert report.derivation_markdown(_notebook("### 2.1.1 Gradient\n<!-- BEGIN TODO 2.1.1 -->\nYOUR ANSWER HERE")) == "YOUR ANSWER HERE"


def test_the_name_line():
    assert report.check_name(None) is None
    assert report.check_name("  Ada Lovelace / alovelac ") == "Ada Lovelace / alovelac"
    for bad in ("", "   ", "two\nlines", "x" * 121):
        with pytest.raises(report.ReportError, match="--name"):
            report.check_name(bad)
    # The printed page's margins (CSS page-margin boxes): the name line at the top, "page N of M" at the bottom.
    margins = report.page_margins_css(None)
    assert re.search(rf'@top-right {{ content: "{re.escape(f"{report.NAME_LABEL} {report.NAME_BLANK}")}"; }}', margins)
    assert '@bottom-center { content: "page " counter(page) " of " counter(pages); }' in margins
    assert '"Name / Andrew ID: Ada & Bob"' in report.page_margins_css("Ada & Bob")
    # A name is a CSS string that cannot end itself or the <style> element it is in.
    assert r'"Name / Andrew ID: Ada \"B\" \3c /style\3e  \\"' in report.page_margins_css('Ada "B" </style> \\')


def test_local_fonts_are_embedded_and_missing_ones_dropped(tmp_path):
    font = tmp_path / "Math Regular.woff"
    font.write_bytes(b"wOFF-bytes")
    css = f"src: url('{font.as_uri()}?V=2.7.9') format('woff'); src: url({(tmp_path / 'gone.otf').as_uri()})"
    embedded = report.embed_local_fonts(css)
    assert "url(data:font/woff;base64,d09GRi1ieXRlcw==) format('woff')" in embedded
    assert "url(data:,)" in embedded and "file:" not in embedded


def test_a_file_url_becomes_the_systems_path_drive_letter_and_letters_kept(monkeypatch):
    """The fonts of a page typeset on Windows: ``file:///C:/Users/...`` is ``C:\\Users\\...`` there
    (``url2pathname``, Windows' own: ``nturl2path``), not ``/C:/Users/...``, which names no file. Made to fail once:
    the kit of e0973d3 cut the scheme (``Path(unquote(urlparse(url).path))``) and got ``\\C:\\Users\\...``."""
    import nturl2path
    from pathlib import PureWindowsPath

    monkeypatch.setattr(chromium, "url2pathname", nturl2path.url2pathname)
    monkeypatch.setattr(chromium, "Path", PureWindowsPath)
    url = "file:///C:/Users/%C5%81ukasz%20Zo%C3%AB/hw1/.venv/Lib/site-packages/x/MathJax_Main-Regular.woff"
    path = chromium.file_path(url)
    assert path == PureWindowsPath(r"C:\Users\Łukasz Zoë\hw1\.venv\Lib\site-packages\x\MathJax_Main-Regular.woff")
    assert path.drive == "C:"
    assert chromium.file_path(PureWindowsPath(r"C:\Users\Łukasz Zoë\f.woff").as_uri()) == PureWindowsPath(
        r"C:\Users\Łukasz Zoë\f.woff")
    monkeypatch.undo()
    assert report.embed_local_fonts(f"url('{Path('/no/such/Łukasz Zoë/f.woff').as_uri()}')") == "url(data:,)"


def test_the_report_gives_the_browser_pages_in_its_own_folder_not_the_systems_tmp(tmp_path, monkeypatch):
    """Ubuntu's Chromium is a snap with a /tmp of its own: the pages it typesets, and its profile, are in the
    report's folder, never under the system's temporary folder. Made to fail once: e0973d3 wrote them to
    /tmp/hwtools-report-*."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "system-tmp"))
    (tmp_path / "system-tmp").mkdir()
    import hwtools.report.command as command

    monkeypatch.setattr(command, "chromium_path", lambda: Path("/usr/bin/chromium"))  # the pages go to the scratch folder
    monkeypatch.setattr(command, "_run_notebooks", lambda notebooks, tmp, step: (_ for _ in ()).throw(RuntimeError(str(tmp))))
    with pytest.raises(RuntimeError) as raised:
        report.build_report(tmp_path / "handin" / "report", progress=lambda line: None)
    scratch = Path(str(raised.value))
    assert scratch.parent == tmp_path / "handin" / "report" and not scratch.is_relative_to(tmp_path / "system-tmp")


def _program(path):
    """A stand-in browser at ``path``: an executable file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("")
    path.chmod(0o755)
    return path


def _browsers(monkeypatch, tmp_path, platform):
    """This process as on ``platform``, with no browser anywhere but what the test puts under ``tmp_path``."""
    monkeypatch.setattr(sys, "platform", platform)
    monkeypatch.delenv("HWLIB_CHROMIUM", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    for folder in ("PROGRAMFILES", "PROGRAMFILES(X86)", "LOCALAPPDATA"):
        monkeypatch.setenv(folder, str(tmp_path / folder))


def test_the_pdf_browser_is_found_where_macos_installs_it(tmp_path, monkeypatch):
    _browsers(monkeypatch, tmp_path, "darwin")
    assert Path("/Applications/Google Chrome.app/Contents/MacOS/Google Chrome") in chromium.browser_candidates()
    assert report.chromium_path() is None
    edge = _program(tmp_path / "home/Applications/Microsoft Edge.app/Contents/MacOS/Microsoft Edge")
    assert report.chromium_path() == edge
    chrome = _program(tmp_path / "home/Applications/Google Chrome.app/Contents/MacOS/Google Chrome")
    assert report.chromium_path() == chrome  # Chrome before Edge


def test_the_pdf_browser_is_found_where_windows_installs_it(tmp_path, monkeypatch):
    _browsers(monkeypatch, tmp_path, "win32")
    _program(tmp_path / "bin/chromium")  # PATH is not looked at on Windows
    assert report.chromium_path() is None
    chrome = _program(tmp_path / "LOCALAPPDATA/Google/Chrome/Application/chrome.exe")  # a user's own install
    assert report.chromium_path() == chrome
    edge = _program(tmp_path / "PROGRAMFILES(X86)/Microsoft/Edge/Application/msedge.exe")  # every Windows 10/11 has it
    assert report.chromium_path() == edge
    monkeypatch.delenv("LOCALAPPDATA")  # a folder variable missing is a folder without browsers
    monkeypatch.delenv("PROGRAMFILES(X86)")
    assert report.chromium_path() is None


def test_the_pdf_browser_is_found_on_path_on_linux_and_hwlib_chromium_comes_first(tmp_path, monkeypatch):
    _browsers(monkeypatch, tmp_path, "linux")
    chrome = _program(tmp_path / "bin/google-chrome-stable")
    assert report.chromium_path() == chrome  # before the /usr/bin defaults
    assert Path("/usr/bin/chromium") in chromium.browser_candidates()
    chosen = _program(tmp_path / "my browser")
    monkeypatch.setenv("HWLIB_CHROMIUM", str(chosen))
    assert report.chromium_path() == chosen
    monkeypatch.setenv("HWLIB_CHROMIUM", str(tmp_path / "not there"))  # then only it: no other browser instead
    assert report.chromium_path() is None


def test_the_report_computes_nothing_the_notebooks_compute():
    """No training, sweep, sampling or fitting in the report, and no setting copied: it reads the kernels' values."""
    package = Path(report.__file__).parent
    files = sorted(path for path in package.rglob("*") if path.suffix in (".py", ".j2"))
    assert len(files) >= 10, files  # every module of the package and its templates
    source = "\n".join(path.read_text(encoding="utf-8") for path in files)
    for name in ("train_cartpole_policy", "train_cartpole_policies", "learning_rate_sweep", "random_policy_rewards",
                 "eval_params", "fit", "load_food_cutting", "train_test_split", "geomspace", "BALANCING_PARAMS",
                 "DEFAULT_LEARNING_RATE"):
        assert not re.search(rf"\b{name}\b", source), f"the report uses {name}"
    assert not re.search(r"^[A-Z_]*(RATE|SEED|ITERATIONS|ROLLOUTS|FRACTION)S? = ", source, flags=re.MULTILINE)


def test_without_chromium_the_pages_bring_their_own_mathjax(tmp_path):
    if report.mathjax_dir() is None:
        pytest.skip("jupyter-server-mathjax is not installed (pip install -r requirements.txt)")
    folder = report.copy_mathjax(tmp_path)
    page = report.answers_html("# T\n\n$$a^2$$\n", {}, f"{report.MATHJAX_COPY}/MathJax.js")
    source = re.search(r'<script src="([^"]+)"', page).group(1)
    assert source.startswith("mathjax/MathJax.js?config=")
    config = source.split("config=")[1].split(",")[0]
    assert (folder / "MathJax.js").is_file() and (folder / "config" / f"{config}.js").is_file()
    assert any((folder / "fonts" / "HTML-CSS" / "STIX-Web" / "woff").glob("*.woff"))


def test_bad_out_dirs_are_refused(tmp_path, capsys):
    not_a_folder = tmp_path / "report.txt"
    not_a_folder.write_text("a file")
    assert report.main([str(not_a_folder)]) == 1
    error = capsys.readouterr().err
    assert "exists and is not a directory" in error and str(not_a_folder) in error
    assert not_a_folder.read_text() == "a file"
    with pytest.raises(report.ReportError, match="cannot create OUT_DIR"):
        report.check_out_dir(not_a_folder / "report")


def _latex_tools():
    """Skip (or, in CI, fail) where pdflatex or pdftotext is missing."""
    missing = [tool for tool in ("pdflatex", "pdftotext") if shutil.which(tool) is None]
    if missing:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{', '.join(missing)} missing in CI (.ci/run installs texlive-latex-base and poppler-utils)")
        pytest.skip(f"{', '.join(missing)} not installed (apt-get install texlive-latex-base texlive-latex-recommended)")


def _compile_latex(folder, build):
    """answers.tex in ``folder`` compiled as a student would, with pdflatex twice (for "page N of M") into
    ``build``; returns (the PDF's pages as text, in reading order, the log)."""
    for _ in range(2):
        done = subprocess.run(
            ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", f"-output-directory={build}", report.ANSWERS_TEX],
            cwd=folder, capture_output=True, text=True, timeout=300,
        )
        assert done.returncode == 0, f"answers.tex does not compile:\n{done.stdout[-4000:]}"
    pages = subprocess.run(["pdftotext", "-raw", str(build / "answers.pdf"), "-"], capture_output=True, text=True,
                           check=True).stdout
    return pages.split("\f")[:-1], (build / "answers.log").read_text(encoding="utf-8", errors="replace")


def test_answers_tex_sets_whatever_a_student_writes(tmp_path):
    """Names, parameter labels and --name with LaTeX's special characters compile and print as written."""
    _latex_tools()
    tricky = r"my #1 & 100% guess_{x} ~ ^ \ <ok> | θ"
    p1 = report.problem_one(p1_values(tried={tricky: [0.1, -0.2, -1.0, -0.3]}))
    p2 = report.problem_two(p2_values(), DERIVATION)
    for name, figure in report.make_figures(p1, p2).items():
        report.save_figure(figure, tmp_path, name)
    text, _ = report.answers_latex(report.compute_answers(p1, p2), name='Ada "B" & Co_1 </x>')
    report.write_answers_tex(tmp_path, text)
    pages, _ = _compile_latex(tmp_path, tmp_path)
    words = _words(" ".join(pages))
    assert 'Name / Andrew ID: Ada "B" & Co_1 </x>' in words
    assert f"{tricky} (0.1, -0.2, -1, -0.3)" in words


def test_an_edited_answers_tex_keeps_its_words_when_the_report_runs_again(tmp_path):
    """The student's words are carried into the new answers.tex (the numbers are the new report's); where they
    changed a line the new report changes too, their file stays as it is and the new text is answers.new.tex."""
    template = "\\section{{1.3.3}}\n% Your words: the rate.\n\nrate: {rate}\n\\section{{2.3.2}}\n% Your words: the curve.\n\nacc: {acc}\n"
    first, note = report.write_answers_tex(tmp_path, template.format(rate=1, acc=0.5))
    assert note is None and not words.has_words(tmp_path)
    assert report.write_answers_tex(tmp_path, template.format(rate=2, acc=0.5)) == (first, None)  # no words: rewritten
    text = first.read_text()
    first.write_text(text.replace("% Your words: the rate.\n", "% Your words: the rate.\nI chose it by the sweep.\n")
                     .replace("the curve.\n\n", "the curve.\n\nIt rises fast.\n\n"))
    again, note = report.write_answers_tex(tmp_path, template.format(rate=3, acc=0.9))
    assert "your words are kept" in note and words.has_words(tmp_path)
    assert again.read_text().split("\n", 1)[1] == (template.format(rate=3, acc=0.9)
                                                   .replace("the rate.\n", "the rate.\nI chose it by the sweep.\n")
                                                   .replace("the curve.\n\n", "the curve.\n\nIt rises fast.\n\n"))
    mine = again.read_text().replace("rate: 3", "rate: 3 (my own)")
    again.write_text(mine)
    _, note = report.write_answers_tex(tmp_path, template.format(rate=4, acc=0.9))
    assert "kept as you wrote it" in note and again.read_text() == mine
    assert (tmp_path / "answers.new.tex").read_text().endswith(template.format(rate=4, acc=0.9))
    _, note = report.write_answers_tex(tmp_path, template.format(rate=5, acc=0.9))  # again: still theirs, new text beside
    assert again.read_text() == mine and (tmp_path / "answers.new.tex").read_text().endswith("rate: 5\n" + template.split("rate: {rate}\n")[1].format(acc=0.9))


def test_without_pandoc_the_derivation_is_kept_as_the_markdown_written(monkeypatch):
    import hwtools.report.latex

    markdown = "Step 1: $\\sigma'(z) = \\sigma(z)(1 - \\sigma(z))$\n\n$$\\nabla l = X^\\top(y - p)$$"
    monkeypatch.setattr(hwtools.report.latex, "pandoc_available", lambda: False)
    latex, note = report.derivation_latex(markdown)
    assert "pandoc was not found" in note
    assert f"\\begin{{verbatim}}\n{markdown}\n\\end{{verbatim}}" in latex
    assert "not found: the notebook has no 2.1.1 heading" in report.derivation_latex(None)[0]


# --- part 2: one run of the command ----------------------------------------------------------------


@pytest.fixture(scope="module")
def windows_home(tmp_path_factory):
    """The Windows user's home (``USERPROFILE``) of the report's Python."""
    return tmp_path_factory.mktemp("home")


@pytest.fixture(scope="module")
def report_run(tmp_path_factory, windows_home):
    """Run the command as a student would (the hand-in runs it too: ``hwtools.handin.build_report``): in a
    student edition whose every TODO is done, in a folder named as a student's may be ("Łukasz Zoë/hw1"), with a
    Python like a student's on Windows (the newest tested version where this machine has it, and every process
    of it as Windows does, "win32" to the kit, with a home of its own and a Chrome where Windows installs one:
    ``foreign_os``), from another folder, into the folder where the hand-in puts it (``handin/report``, which does
    not exist yet). Its output is read as Windows writes a pipe (cp1252)."""
    import editions

    from hwtools.todos import TODO_BY_ID

    edition = editions.build(tmp_path_factory.mktemp("edition") / "Łukasz Zoë" / "hw1", tmp_path_factory,
                             keep=frozenset(TODO_BY_ID))
    python = student_python(tmp_path_factory.mktemp("venv") / "venv", system="windows", home=windows_home,
                            base=find_python(versions_tested()[-1]))
    out_dir = edition / "handin" / "report"
    command = [str(python), "-m", "hwtools.report", str(out_dir), "--name", STUDENT_NAME]
    done = subprocess.run(command, capture_output=True, encoding="cp1252", errors="replace", timeout=REPORT_TIMEOUT,
                          env=kit_env(edition, python), cwd=tmp_path_factory.getbasetemp())
    assert done.returncode == 0, f"the report failed:\n{done.stdout}\n{done.stderr}"
    return out_dir, done.stdout, edition, python


@pytest.fixture(scope="module")
def out_dir(report_run):
    return report_run[0]


@pytest.fixture(scope="module")
def answers_md(out_dir):
    return (out_dir / report.ANSWERS_MD).read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def printed(out_dir):
    """{notebook file name: the text its cells printed when the report executed it}."""
    return {name: output_text((out_dir / name.replace(".ipynb", ".html")).read_text(encoding="utf-8"))
            for name in report.NOTEBOOKS}


@pytest.fixture(scope="module")
def pdf(report_run):
    out_dir, stdout = report_run[:2]
    if report.chromium_path() is None:
        if os.environ.get("CI") == "true":
            pytest.fail("Chromium is missing in CI, so answers.pdf was not printed (.ci/run installs Debian's chromium)")
        assert "PDF: SKIPPED" in stdout
        pytest.skip("Chromium is not installed (apt-get install chromium): answers.pdf is not printed here")
    if shutil.which("pdftotext") is None or shutil.which("pdftoppm") is None:
        if os.environ.get("CI") == "true":
            pytest.fail("poppler-utils is missing in CI, so answers.pdf cannot be checked (.ci/run must install it)")
        pytest.skip("poppler-utils is not installed (apt-get install poppler-utils): the PDF cannot be read here")
    path = out_dir / report.ANSWERS_PDF
    assert path.read_bytes().startswith(b"%PDF")
    pages = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True, check=True).stdout
    return path, pages.split("\f")[:-1]


def test_progress_says_what_was_read_from_each_kernel(report_run):
    stdout = report_run[1]
    for index, name in enumerate(report.NOTEBOOKS, start=1):
        assert f"notebook {index}/2: executing {name}" in stdout
        assert f"read {', '.join(report.NOTEBOOK_VARIABLES[name])} from its kernel" in stdout
    assert "answers: written" in stdout and "report complete" in stdout
    assert "WARNING" not in stdout and "NOT TYPESET" not in stdout


def test_the_sweeps_result_is_kept_where_windows_keeps_a_users_caches(report_run, windows_home):
    r"""The report's run of p1 on the Windows profile keeps the learning-rate sweep's result in %LOCALAPPDATA%\hwlib.
    Made to fail once: without ``reuse.folder``'s Windows branch it was kept in ~/.cache/hwlib."""
    kept = [path.parent for path in windows_home.rglob("sweep-*.npz")]
    assert kept == [windows_home / "AppData" / "Local" / "hwlib"], kept


def test_the_pdf_is_printed_with_the_chrome_where_windows_installs_it(report_run, pdf):
    """No browser is on the Windows profile's PATH: the report finds the Chrome in %PROGRAMFILES% (a link to this box's
    Chromium). Made to fail once: without ``browser_candidates``' Windows branch it printed with /usr/bin/chromium."""
    chrome = Path(report_run[3]).parents[1].joinpath(foreign_os.PROGRAM_FILES, *foreign_os.CHROME)
    assert f"in {chrome} ..." in report_run[1], report_run[1]


def _assert_reads_offline(page, name):
    assert page.lstrip().lower().startswith("<!doctype html>"), name
    assert "$$" not in page, f"{name}: raw TeX left"
    assert "Math Processing Error" not in page, name
    assert 'class="MathJax"' in page, f"{name}: no typeset formula"
    assert "<script" not in page, f"{name}: a script is left (the saved page needs none)"
    assert "file://" not in page, f"{name}: refers to a file of this machine"
    assert not re.search(r"""(?:<link[^>]*href|src)=["']?https?:|url\(["']?https?:""", page), f"{name}: loads from the network"


@pytest.mark.parametrize("notebook", report.NOTEBOOKS)
def test_executed_notebook_as_html_reads_offline(out_dir, notebook):
    page = (out_dir / notebook.replace(".ipynb", ".html")).read_text(encoding="utf-8")
    title = report.notebook_title(report.NOTEBOOK_DIR / notebook)
    assert title in page or html.escape(title) in page, f"the title {title!r} is not in the HTML"
    assert "data:image/png;base64," in page  # executed with inline figures
    assert "Traceback" not in page
    _assert_reads_offline(page, notebook)


@pytest.mark.parametrize("name", report.FIGURES)
def test_figure_png_is_the_width_of_the_page(out_dir, name):
    data = (out_dir / name).read_bytes()
    assert data.startswith(PNG_SIGNATURE), f"{name} is not a PNG"
    width = int.from_bytes(data[16:20], "big")
    assert width == round(PRINT_WIDTH * report.FIGURE_DPI), f"{name} is {width} px wide"


def test_answers_md_links_every_figure(answers_md, out_dir):
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", answers_md)
    assert sorted(linked) == sorted(report.FIGURES)
    assert all((out_dir / name).is_file() for name in linked)


def test_answers_html_reads_offline_with_the_figures_inline(out_dir):
    page = (out_dir / report.ANSWERS_HTML).read_text(encoding="utf-8")
    _assert_reads_offline(page, report.ANSWERS_HTML)
    assert page.count('<div class="figure"><svg') == len(report.FIGURES)
    assert len(re.findall(rf'<svg [^>]*width="{PRINT_WIDTH * 72:g}pt"', page)) == len(report.FIGURES)
    assert STUDENT_NAME in page


def test_the_pages_have_no_serious_accessibility_violation(out_dir):
    """axe-core (``tests/instructor/accessibility.py``) on answers.html and the executed notebooks' pages, as
    Chromium shows them: no serious or critical violation (contrast, links told by colour alone, names, alt)."""
    if report.chromium_path() is None:
        if os.environ.get("CI") == "true":
            pytest.fail("Chromium is missing in CI, so the pages cannot be checked (.ci/run installs Debian's chromium)")
        pytest.skip("Chromium is not installed (apt-get install chromium): the pages cannot be checked here")
    from accessibility import serious_violations
    from playwright.sync_api import sync_playwright

    found = {}
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(report.chromium_path()), args=report.CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            for name in (report.ANSWERS_HTML, *(notebook.replace(".ipynb", ".html") for notebook in report.NOTEBOOKS)):
                page.goto((out_dir / name).as_uri())
                found[name] = serious_violations(page)
        finally:
            browser.close()
    assert not any(found.values()), "axe-core on the report's pages:\n" + "\n".join(
        f"{name}: {line}" for name, lines in found.items() for line in lines)


# --- the numbers: the notebooks' own, printed the same way ---------------------------------------------


def _bullet(answers_md, label):
    """The value of answers.md's line '- label: value': the bold part if there is one, else the whole rest."""
    match = re.search(rf"^- {re.escape(label)}: (.+)$", answers_md, flags=re.MULTILINE)
    assert match, f"answers.md has no line '- {label}: ...'"
    bold = re.match(r"\*\*(.+?)\*\*", match.group(1))
    return bold.group(1) if bold else match.group(1)


# How each notebook prints the numbers answers.md gives (label -> the print line): the same format in both.
PRINTED_AS = {
    report.P1_NOTEBOOK: {
        "median reward": 'print(f"median reward: {np.median(random_rewards):.1f}")',
        "learning rate": 'print(f"learning rate: {learning_rate:g}")',
        "reward per iteration": 'print("reward per iteration:", ", ".join(f"{reward:.1f}" for reward in run.rewards))',
        f"converged ({settings.MAX_EPISODE_STEPS} from then on) at iteration":
            'print(f"converged ({cartpole.MAX_EPISODE_REWARD} from then on) at iteration:", converged_at)',
        "final parameters": 'print("final parameters: [" + ", ".join(f"{value:.3f}" for value in run.policy.params) + "]")',
    },
    report.P2_NOTEBOOK: {
        "data": 'print(f"data: {data.source}")',
        "final train accuracy": 'print(f"final train accuracy: {train_accuracies[-1]:.3f}")',
        "test accuracy": 'print(f"test accuracy: {test_accuracy:.3f}")',
        "first iteration with train accuracy above 99%": 'print(f"first iteration with train accuracy above 99%: {first_above_99}")',
    },
}


@pytest.mark.parametrize("notebook, label", [(notebook, label) for notebook in PRINTED_AS for label in PRINTED_AS[notebook]])
def test_numbers_are_given_as_the_notebook_prints_them(answers_md, printed, notebook, label):
    value = _bullet(answers_md, label)
    assert re.search(rf"^{re.escape(label)}:\s+{re.escape(value)}$", printed[notebook], flags=re.MULTILINE), (
        f"{notebook} does not print '{label}: {value}' as answers.md gives it; print it with {PRINTED_AS[notebook][label]}"
    )


def test_random_policy_share_and_sweep_are_the_notebooks(answers_md, printed):
    sentence = re.search(rf"^- (\d+ of \d+ random policies reached the maximum reward of {settings.MAX_EPISODE_STEPS}): \*\*([\d.]+%)\*\*$", answers_md,
                         flags=re.MULTILINE)
    assert sentence and f"{sentence.group(1)}: {sentence.group(2)}" in printed[report.P1_NOTEBOOK]
    rates = re.search(r"^\| learning rate \| (.+) \|$", answers_md, flags=re.MULTILINE).group(1).split(" | ")
    shares = re.search(r"^\| converged \| (.+) \|$", answers_md, flags=re.MULTILINE).group(1).split(" | ")
    for rate, share in zip(rates, shares, strict=True):
        assert re.search(rf"learning rate {re.escape(rate)}:\s+{re.escape(share)} of", printed[report.P1_NOTEBOOK])


def test_hand_tuning_table_is_the_notebooks_tried(answers_md, out_dir):
    notebook_page = html.unescape(re.sub(r"<[^>]+>", "", (out_dir / f"{Path(report.P1_NOTEBOOK).stem}.html").read_text()))
    rows = re.findall(r"^\| (.+?) \| \(([^)]*)\) \| .+? \| ([\d, ]+) \|$", answers_md, flags=re.MULTILINE)
    assert rows, "answers.md has no 1.1.2 table"
    for name, params, rewards in rows:
        assert name in notebook_page, f"{name!r} is not a name of the notebook's tried"
        params = [float(value) for value in params.split(", ")]
        expected = [int(run_policy(CartPoleLinearPolicy(params), seed=seed)) for seed in settings.HAND_TUNING_SEEDS]
        assert [int(value) for value in rewards.split(", ")] == expected


def test_the_derivation_is_the_notebooks(answers_md):
    stored = nbformat.read(report.NOTEBOOK_DIR / report.P2_NOTEBOOK, as_version=4)
    derivation = report.derivation_markdown(stored)
    assert derivation and derivation in answers_md


# --- the PDF -----------------------------------------------------------------------------------------


def _ink_rows(pdf_path, tmp_path):
    """Per page, whether each pixel row of the printable area (inside the margins) has ink; from pdftoppm renders."""
    subprocess.run(["pdftoppm", "-gray", "-r", "30", str(pdf_path), str(tmp_path / "page")], check=True)
    pages = []
    for path in sorted(tmp_path.glob("page-*.pgm"), key=lambda path: int(path.stem.split("-")[1])):
        data = path.read_bytes()
        _, width, height, _, pixels = re.match(rb"(P5)\s+(\d+)\s+(\d+)\s+(\d+)\s(.*)", data, flags=re.DOTALL).groups()
        image = np.frombuffer(pixels, dtype=np.uint8).reshape(int(height), int(width))
        top, bottom = round(int(height) * 18 / 297), round(int(height) * (297 - 16) / 297)
        pages.append((image[top:bottom] < 200).any(axis=1))
    return pages


def _assert_numbered_with_the_name(pages, title, fewest, most):
    assert fewest <= len(pages) <= most, f"{len(pages)} pages"
    for number, text in enumerate(pages, start=1):
        assert f"page {number} of {len(pages)}" in text
        assert f"{report.NAME_LABEL} {STUDENT_NAME}" in text
    assert title in pages[0]


def test_pdf_pages_are_numbered_and_carry_the_name(pdf):
    _assert_numbered_with_the_name(pdf[1], "Robot Autonomy — Homework 1: answers", 3, 6)


def test_pdf_has_no_blank_half_pages(pdf, tmp_path):
    path, _ = pdf
    pages = _ink_rows(path, tmp_path)
    for number, rows in enumerate(pages, start=1):
        inked = np.flatnonzero(rows)
        assert inked.size, f"page {number} is empty"
        if number < len(pages):
            blank_below = 1 - (inked[-1] + 1) / rows.size
            assert blank_below < 1 / 3, f"page {number}: the bottom {blank_below:.0%} is blank"


def _words(text):
    return " ".join(text.split())


def test_pdf_typesets_the_derivation(pdf):
    _, pages = pdf
    text = _words(" ".join(pages))
    assert "$" not in text and "\\frac" not in text and "\\tilde" not in text and "Math Processing Error" not in text
    stored = nbformat.read(report.NOTEBOOK_DIR / report.P2_NOTEBOOK, as_version=4)
    prose = re.sub(r"\$\$.*?\$\$|\$[^$]*\$", "\n", report.derivation_markdown(stored), flags=re.DOTALL)
    pieces = [_words(piece.replace("**", "")) for piece in re.split(r"[\n.:;,]", prose)]
    pieces = [piece for piece in pieces if len(piece.split()) >= 3]
    assert pieces, "the derivation has no prose to look for"
    missing = [piece for piece in pieces if piece not in text]
    assert not missing, f"not in the PDF: {missing}"


def _figure_labels(answers_md):
    """The labels the five figures print, as answers.md's numbers say they must read."""
    share = re.search(rf"^- (\d+) of (\d+) random policies reached the maximum reward of {settings.MAX_EPISODE_STEPS}: \*\*([\d.]+%)\*\*", answers_md,
                      flags=re.MULTILINE).groups()
    converged = _bullet(answers_md, f"converged ({settings.MAX_EPISODE_STEPS} from then on) at iteration")
    return (
        f"reward {settings.MAX_EPISODE_STEPS}: {share[0]} of {share[1]} ({share[2]})",
        f"deadline: iteration {settings.CONVERGENCE_DEADLINE}",
        f"converged at iteration {converged}",
        "Learning-rate sweep",
        "chosen learning rate",
        f"deadline: iteration {settings.TARGET_ITERATIONS}",
        "Confusion matrix of the test set",
    )


def _assert_figures_carry_their_labels(text, answers_md, document):
    for label in _figure_labels(answers_md):
        assert label in text, f"{label!r} is not in {document}"
    source = _bullet(answers_md, "data")
    labels = re.findall(rf"data: {re.escape(source)}(?! —)", text)  # the figures' labels, not answers.md's line
    assert len(labels) == 2, f"{document}: each problem 2 figure must say which data it came from"


def test_pdf_figures_carry_their_labels(pdf, answers_md):
    _, pages = pdf
    _assert_figures_carry_their_labels(_words(" ".join(pages)), answers_md, "answers.pdf")


def _pdf_info(path):
    info = subprocess.run(["pdfinfo", str(path)], capture_output=True, text=True, check=True).stdout
    return dict(line.split(":", 1) for line in info.splitlines() if ":" in line)


def test_pdf_is_a4_from_debians_chromium_with_the_formulas_own_fonts(pdf, out_dir):
    """nbconvert's webpdf exporter printed it in Debian's Chromium (not a browser Playwright downloaded), on the
    page's own paper, and MathJax's web fonts had loaded: no formula fell back to a system font."""
    path, _ = pdf
    info = _pdf_info(path)
    assert "(A4)" in info["Page size"], info["Page size"]
    version = subprocess.run([str(report.chromium_path()), "--version"], capture_output=True, text=True).stdout
    major = re.search(r"(\d+)\.\d+\.\d+", version).group(1)
    assert f"HeadlessChrome/{major}." in info["Creator"], f"printed by {info['Creator']!r}, not {version.strip()}"
    fonts = subprocess.run(["pdffonts", str(path)], capture_output=True, text=True, check=True).stdout.splitlines()[2:]
    web_fonts = [line for line in fonts if line.startswith("[none]")]  # MathJax's STIX web fonts
    named = {re.sub(r"^[A-Z]{6}\+", "", line.split()[0]) for line in fonts if not line.startswith("[none]")}
    assert web_fonts, "no MathJax web font in the PDF: the formulas were printed in system fonts"
    assert named <= {"DejaVuSans", "DejaVuSans-Bold", "DejaVuSans-Oblique", "DejaVuSans-BoldOblique", "DejaVuSansMono"}, (
        f"fonts the page does not ask for (a formula fell back to them): {sorted(named)}")


# --- answers.tex, compiled as a student would ------------------------------------------------------------


@pytest.fixture(scope="module")
def latex(out_dir, tmp_path_factory):
    """answers.tex compiled beside its figures with pdflatex (twice): its pages as text, in reading order."""
    _latex_tools()
    pages, log = _compile_latex(out_dir, tmp_path_factory.mktemp("latex"))
    return pages, log


def _flat(text):
    """Text as pdftotext gives it and as answers.md writes it, made comparable: one space between words, plain quotes,
    no Markdown emphasis."""
    return _words(text.replace("\u2019", "'").replace("**", "").replace("`", ""))


def test_latex_compiles_cleanly_and_its_pages_carry_the_name(latex):
    pages, log = latex
    assert "Missing character" not in log and "undefined references" not in log, "a character or reference LaTeX lacks"
    _assert_numbered_with_the_name(pages, "Robot Autonomy — Homework 1", 2, 8)


def test_latex_holds_every_number_of_answers_md(latex, answers_md):
    text = _flat(" ".join(latex[0]))
    bullets = re.findall(r"^- (.+)$", answers_md, flags=re.MULTILINE)
    assert len(bullets) >= 10
    for bullet in bullets:
        assert _flat(bullet) in text, f"answers.tex does not give: {_flat(bullet)}"
    rates = re.search(r"^\| learning rate \| (.+) \|$", answers_md, flags=re.MULTILINE).group(1).split(" | ")
    shares = re.search(r"^\| converged \| (.+) \|$", answers_md, flags=re.MULTILINE).group(1).split(" | ")
    for rate, share in zip(rates, shares, strict=True):
        assert f"{rate} {share}" in text, f"the sweep's row {rate}: {share} is not in answers.tex"
    rows = re.findall(r"^\| (.+?) \| (\([^)]*\)) \| .+? \| ([\d, ]+) \|$", answers_md, flags=re.MULTILINE)
    assert rows
    for name, params, rewards in rows:
        assert re.search(rf"{re.escape(html.unescape(name))} {re.escape(params)} .+? {re.escape(rewards)}", text), (
            f"the 1.1.2 row {name} is not in answers.tex")


def test_latex_figures_are_the_pdf_files_beside_it(latex, out_dir, answers_md):
    source = (out_dir / report.ANSWERS_TEX).read_text(encoding="utf-8")
    included = re.findall(r"\\includegraphics\[[^\]]*\]\{([^}]+)\}", source)
    assert included == [report.pdf_name(name) for name in report.FIGURES]
    for name in included:
        assert (out_dir / name).read_bytes().startswith(b"%PDF"), f"{name} is not a PDF beside answers.tex"
    _assert_figures_carry_their_labels(_flat(" ".join(latex[0])), answers_md, "answers.tex")


def test_latex_typesets_the_students_derivation(latex):
    if not report.pandoc_available():
        if os.environ.get("CI") == "true":
            pytest.fail("pandoc is missing in CI (.ci/run installs it): the 2.1.1 derivation was not converted")
        pytest.skip("pandoc is not installed (apt-get install pandoc): the 2.1.1 derivation is in answers.tex as Markdown")
    text = _flat(" ".join(latex[0]))
    assert "$" not in text and "\\frac" not in text and "\\tilde" not in text and "\\[" not in text
    stored = nbformat.read(report.NOTEBOOK_DIR / report.P2_NOTEBOOK, as_version=4)
    prose = re.sub(r"\$\$.*?\$\$|\$[^$]*\$", "\n", report.derivation_markdown(stored), flags=re.DOTALL)
    pieces = [_flat(piece) for piece in re.split(r"[\n.:;,]", prose)]
    pieces = [piece for piece in pieces if len(piece.split()) >= 3]
    assert pieces, "the derivation has no prose to look for"
    squashed = re.sub(r"[\s-]", "", text)  # LaTeX breaks words at line ends; compare the letters
    missing = [piece for piece in pieces if re.sub(r"[\s-]", "", piece) not in squashed]
    assert not missing, f"not in answers.tex: {missing}"


# --- every cell prints what it printed on Linux (issue 39.4; on macOS and a hub: test_other_systems.py) -------------


def test_every_cell_prints_what_it_prints_on_linux(report_run, tmp_path):
    """Each cell of both notebooks that nbval compares, the check cells and the learning-rate sweep among them, run by
    the report in a kernel of the Windows profile's Python, prints what it prints on Linux. Made to fail once: with the
    grader's child in the code page (no UTF-8 mode, no ``printable_output``) the report stopped at check("1.1.1"):
    "The check could not run: ... UnicodeEncodeError: 'charmap' codec can't encode character '\\u0141'"."""
    out_dir, _, edition, _ = report_run
    assert_printed_as_on_linux(out_dir, linux_check_texts(edition, tmp_path))


# --- the student's words through later hand-ins (this test changes the report's folder: it runs last) ------------


def _hand_in(report_run, *options):
    _, _, edition, python = report_run
    done = subprocess.run([str(python), "-m", "hwtools.handin", "alovelac", "--name", "Ada Lovelace", *options],
                          capture_output=True, encoding="cp1252", errors="replace", timeout=REPORT_TIMEOUT,
                          env=kit_env(edition, python), cwd=edition)
    assert done.returncode == 0, f"the hand-in failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout.strip().splitlines()


@pytest.mark.timeout(3 * REPORT_TIMEOUT)
def test_later_hand_ins_keep_the_students_words_and_name_the_pdf_to_upload(report_run):
    """Issue 39.2, on the Windows profile in "Łukasz Zoë/hw1": the student writes words at the "% Your words" lines
    of handin/report/answers.tex and compiles it there with pdflatex; a hand-in then names that PDF for upload (as
    handin/alovelac.pdf). They write more, and hand in again with a new report: their words are in its new
    answers.tex, the new report's numbers around them, and the hand-in says their PDF is older than their
    answers.tex; compiled again, the PDF holds every word. (e0973d3's hand-in loses the words: its unit-level twin,
    test_student_path's ``test_the_students_words_and_files_survive_every_later_report``, failed there.)"""
    _latex_tools()
    out_dir, _, edition, _ = report_run
    tex = out_dir / report.ANSWERS_TEX
    mine = ["My first words: the sweep shows every seed converging at the rate I chose.",
            "My second words: the confusion matrix mixes up only two foods."]
    text = tex.read_text(encoding="utf-8")
    comments = re.findall(r"^% Your words:.*$", text, flags=re.M)
    text = text.replace(comments[0], f"{comments[0]}\n{mine[0]}", 1)
    tex.write_text(text, encoding="utf-8")
    pages, _ = _compile_latex(out_dir, out_dir)
    assert mine[0] in _words(" ".join(pages))
    said = _hand_in(report_run, "--no-report")
    upload = edition / "handin" / "alovelac.pdf"
    assert upload.read_bytes() == (out_dir / report.ANSWERS_PDF).read_bytes()
    assert said[-1].startswith("Hand in ") and "alovelac.pdf on Gradescope." in said[-1], said[-3:]
    tex.write_text(tex.read_text(encoding="utf-8").replace(comments[-1], f"{comments[-1]}\n{mine[1]}", 1), encoding="utf-8")
    said = _hand_in(report_run)
    text = tex.read_text(encoding="utf-8")
    assert all(words in text for words in mine) and len(re.findall(r"^% Your words:", text, flags=re.M)) == len(comments)
    assert any("your words are kept in the new answers.tex" in line for line in said), said
    assert any("answers.pdf there is older than your answers.tex" in line for line in said), said
    assert "once made, the report's PDF on Gradescope" in said[-1], said[-3:]
    assert upload.read_bytes().startswith(b"%PDF") and all((out_dir / name).is_file() for name in report.FIGURES)
    pages, _ = _compile_latex(out_dir, out_dir)
    assert all(words in _words(" ".join(pages)) for words in mine)

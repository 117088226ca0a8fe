"""The instructor's side of the grader, never in the student edition (``instructor/kit.py``
``INSTRUCTOR_ONLY`` leaves this folder out whole): Linux's sandbox launchers (``bwrap_sandbox``:
bubblewrap, and ``zygote``: one such sandbox per grading, whose PID 1, ``zygote_init``, forks its runs;
``user_sandbox`` and ``confine``: the fallback without namespaces, a user of its own per
run and a seccomp filter; ``cgroups``: a run bounded as a whole), and a class's grading
(``classroom``: running one; ``gradebook``; ``class_feedback``: Markdown; ``class_summary``: each
check's pass rate and each named mistake's count; ``class_progress``: the terminal's progress line;
``gradescope_autograder``: Gradescope's container, built by ``instructor/gradescope_bundle.py``).

The student's side (``hwtools/grade/`` outside this folder: the preview, the check cells, the
hand-in's checks) imports from here only where it may be missing: the student edition then runs
the preview unsandboxed, and a folder of submissions is refused.
"""

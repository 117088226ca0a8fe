"""axe-core on a page the browser tests show (the slider panel, a check cell's output, the report's HTML).

axe-core (Deque's accessibility engine) comes in the ``axe-playwright-python`` package, which ships its
``axe.min.js``: nothing is downloaded at test time. ``serious_violations(page, selector)`` runs it on the
elements ``selector`` names (the whole page if None) and returns the violations whose impact is serious
or critical, each as one line: the rule, its impact, its help text and the elements it found.
"""

from __future__ import annotations

FAILING_IMPACTS = ("serious", "critical")


def axe_results(page, selector=None):
    """axe-core's full answer (a dict) for the elements ``selector`` names, or the whole page."""
    from axe_playwright_python.sync_playwright import Axe  # noqa: PLC0415 - only the browser tests need it

    return Axe().run(page, context=selector, options={"resultTypes": ["violations"]}).response


def serious_violations(page, selector=None):
    """The serious and critical violations axe-core finds, one line each (empty: none)."""
    results = axe_results(page, selector)
    return [
        f"{violation['id']} ({violation['impact']}): {violation['help']}: "
        + "; ".join(" ".join(node["target"]) if isinstance(node["target"], list) else str(node["target"])
                    for node in violation["nodes"][:6])
        for violation in results["violations"] if violation["impact"] in FAILING_IMPACTS
    ]

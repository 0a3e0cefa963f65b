"""The report's title-page note: which code its numbers come from, and whether the build was quick."""

from __future__ import annotations

from stslam.render.report_tables import latex_escape


def _define(name: str, body: str) -> str:
    return f"\\expandafter\\def\\csname {name}\\endcsname{{{body}}}\n"


def provenance_text(origins: list, head_sha: str, head_dirty: bool) -> str:
    """One LaTeX paragraph: every run's code is the current code, or the runs whose code is not.

    ``origins`` are :class:`stslam.experiments.reproduce.CodeOrigin` records (``key``,
    ``at_head``, ``reason``: None when the run's code is current).

    A run's code is current when it was made from a clean tree at a commit whose files the run
    depends on equal those on disk now (:func:`stslam.experiments.reproduce.code_reason`): at
    HEAD, or at an earlier commit that changed none of them.
    """
    head = f"git \\texttt{{{latex_escape(head_sha)}}}" + (", with uncommitted changes" if head_dirty else "")
    stale = [o for o in origins if o.reason is not None]
    if not origins:
        return ""
    if not stale:
        n, at_head = len(origins), sum(o.at_head for o in origins)
        runs = "its run was" if n == 1 else f"its {n} runs were"
        if at_head == n:
            where = f"{runs} made at this commit from a clean tree."
        elif at_head == 0:
            where = (f"{runs} made from clean trees at earlier commits, and no file "
                     f"{'it depends' if n == 1 else 'they depend'} on has changed since.")
        else:
            where = (f"{at_head} of its {n} runs were made at this commit and {n - at_head} at earlier commits, "
                     "all from clean trees, and no file they depend on has changed since.")
        return f"Every number in this report comes from the current code ({head}): {where}"
    by_reason: dict[str, list[str]] = {}
    for origin in stale:
        by_reason.setdefault(origin.reason, []).append(f"\\texttt{{{latex_escape(origin.key)}}}")
    listed = "; ".join(f"{', '.join(keys)} ({latex_escape(reason)})" for reason, keys in by_reason.items())
    return (f"Not every number in this report comes from the current code ({head}). "
            f"{len(stale)} of its {len(origins)} runs were made from other code: {listed}.")


QUICK_TEXT = ("\\textbf{Quick build.} The runs behind this report used the small seed counts of "
              "\\texttt{experiments/reproduce.py {-}{-}quick}: a first look, not the numbers the text describes.")


def provenance_macros(origins: list, head_sha: str, head_dirty: bool, quick: bool) -> str:
    """``\\reportprovenance`` (the title-page note) and ``\\reportquick`` (empty unless ``quick``)."""
    return (_define("reportprovenance", provenance_text(origins, head_sha, head_dirty))
            + _define("reportquick", QUICK_TEXT if quick else ""))

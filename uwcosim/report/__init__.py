"""The report stage: figures, ``report.md`` and ``report.html`` from a run's (or a campaign's)
files alone. ``uwcosim report PATH`` picks the kind from what the folder holds; of a run it
rebuilds ``summary.json`` too (the evaluate stage)."""

from __future__ import annotations

import sys
import types
from pathlib import Path

from uwcosim.errors import UwcosimError
from uwcosim.report.run_report import report_run


def report_campaign(campaign_dir: str | Path, out: str | Path | None = None,
                    html: bool = False) -> Path:
    """Tables, figures and ``report.md`` (and ``report.html``) of a campaign directory."""
    from uwcosim.campaign.driver import collect

    campaign_dir = Path(campaign_dir)
    out = Path(out) if out is not None else campaign_dir
    out.mkdir(parents=True, exist_ok=True)
    summary = collect(campaign_dir, figures=True, out=out)
    if not summary.get("runs"):
        raise UwcosimError(f"{campaign_dir / 'results'}: no run results to report")
    path = out / "report.md"
    if html:
        from uwcosim.plots.html import campaign_html

        path = campaign_html(campaign_dir, summary, out / "report.html")
    return path


def report(path: str | Path, out: str | Path | None = None, html: bool = False) -> Path:
    """Report of a run directory (``log.parquet``) or a campaign directory (``results/``).

    A run's ``summary.json`` is rebuilt first (:func:`uwcosim.evaluation.evaluate`, into
    ``out`` when given), so any run -- interrupted, or made by an older version -- gets its
    summary, figures and report from its files alone. Returns the report's path."""
    path = Path(path)
    if (path / "log.parquet").is_file():
        from uwcosim.evaluation.summary import evaluate

        return report_run(path, out, html, summary=evaluate(path, out))
    if (path / "results").is_dir():
        return report_campaign(path, out, html)
    raise UwcosimError(f"{path}: neither a run directory (no log.parquet) nor a campaign "
                       f"directory (no results/)")


class _CallableModule(types.ModuleType):
    """Importing this package binds it to ``uwcosim.report``, which would then shadow the
    function of the same name for ``from uwcosim import report``: calling the package is
    calling :func:`report`."""

    def __call__(self, path: str | Path, out: str | Path | None = None,
                 html: bool = False) -> Path:
        return report(path, out, html)


sys.modules[__name__].__class__ = _CallableModule

__all__ = ["report", "report_campaign", "report_run"]

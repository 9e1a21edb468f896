"""The report of a campaign directory: tables, figures, ``report.md`` and ``report.html``,
from its ``results/`` alone."""

from __future__ import annotations

from pathlib import Path

from uwcosim.campaign.driver import collect
from uwcosim.campaign.html import campaign_html
from uwcosim.core.errors import UwcosimError


def report_campaign(campaign_dir: str | Path, out: str | Path | None = None,
                    html: bool = False) -> Path:
    """Tables, figures and ``report.md`` (and ``report.html``) of a campaign directory."""
    campaign_dir = Path(campaign_dir)
    out = Path(out) if out is not None else campaign_dir
    out.mkdir(parents=True, exist_ok=True)
    summary = collect(campaign_dir, figures=True, out=out)
    if not summary.get("runs"):
        raise UwcosimError(f"{campaign_dir / 'results'}: no run results to report")
    path = out / "report.md"
    if html:
        path = campaign_html(campaign_dir, summary, out / "report.html")
    return path

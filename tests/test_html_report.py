"""``uwcosim report --html``: one self-contained page per run or campaign, checked in a real
headless Chromium (no console message, every plot drawn, a screenshot that is not blank)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.browser import find_chromium, load_page
from uwcosim.api import run_scenario
from uwcosim.cli import main
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]

CAMPAIGN = """
name = "h"
seed = 3
runs = 2
[[variants]]
name = "without_terrain"
scenario = "{root}/scenarios/tan_dead_reckoning.toml"
set = ["run.duration=20"]
[[variants]]
name = "with_terrain"
scenario = "{root}/scenarios/tan_terrain.toml"
set = ["run.duration=20"]
"""


@pytest.fixture(scope="module")
def chromium() -> str:
    path, why = find_chromium()
    if path is None:
        pytest.skip(why)
    return path


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, project_fmus) -> Path:
    out = tmp_path_factory.mktemp("run")
    run_scenario(load_scenario(ROOT / "scenarios" / "tan_terrain.toml", ["run.duration=120"]),
                 out)
    assert main(["report", str(out), "--html"]) == 0
    return out


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory, project_fmus) -> Path:
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign

    tmp = tmp_path_factory.mktemp("campaign")
    spec = tmp / "c.toml"
    spec.write_text(CAMPAIGN.format(root=ROOT))
    run_campaign(load_campaign(spec), tmp / "out", workers=1, figures=False)
    assert main(["report", str(tmp / "out"), "--html"]) == 0
    return tmp / "out"


def _self_contained(page: str) -> None:
    assert not re.search(r"<(script|img|link|iframe)[^>]+(src|href)=\"(https?:)?//", page)
    assert "<link" not in page and 'src="http' not in page
    assert "Plotly.newPlot" in page


def test_run_page_holds_provenance_table_and_plots(run_dir):
    page = (run_dir / "report.html").read_text()
    _self_contained(page)
    _, meta = read_log(run_dir / "log.parquet")
    assert f"Seed <b>{meta['seed']}</b>" in page
    for name, sha in meta["fmus"].items():
        assert name in page and sha in page
    for pkg, ver in meta["versions"].items():
        assert f"<td>{pkg}</td><td>{ver}</td>" in page
    assert "[estimators.pfm_psi]" in page and "uwcosim run " in page
    for div in ("plot-trajectory", "plot-states", "plot-errors"):
        assert f'id="{div}"' in page
    pngs = sorted(p.name for p in run_dir.glob("*.png"))
    assert len(pngs) == 5  # three run figures, density snapshots at t = 10 s and 100 s
    assert page.count('<img alt="') == len(pngs)
    assert all(f"<figcaption>{p}</figcaption>" in page for p in pngs)
    # deterministic: the same run gives the same page
    first = page
    assert main(["report", str(run_dir), "--html"]) == 0
    assert (run_dir / "report.html").read_text() == first


def test_run_page_trajectory_over_the_bathymetry_equal_aspect_titled_axes(run_dir):
    """Issue 22: the interactive trajectory has the map behind it and equal scales; every
    panel's axes are titled with units; the filters carry their display names."""
    page = (run_dir / "report.html").read_text()
    div = page.index('id="plot-trajectory"')
    spec = page[div:page.index('id="plot-states"')]
    assert '"type":"heatmap"' in spec and '"name":"bathymetry"' in spec
    assert '"scaleanchor":"x"' in spec and '"scaleratio":1' in spec
    assert '"text":"depth (m)"' in spec and '"name":"start"' in spec
    for title in ("x (m)", "y (m)"):
        assert f'"text":"{title}"' in spec, title
    states = page[page.index('id="plot-states"'):page.index('id="plot-errors"')]
    for title in ("x (m)", "y (m)", "vx (m/s)", "vy (m/s)", "time (s)"):
        title = title.replace("/", "\\u002f")  # as Plotly's JSON writes it
        assert f'"text":"{title}"' in states, title
    errors = page[page.index('id="plot-errors"'):]
    _, meta = read_log(run_dir / "log.parquet")
    assert errors.count('"text":"error (m)"') == len(meta["estimators"])
    assert '"name":"Dead reckoning"' in page and '"name":"PFM-PSI"' in page
    assert '"name":"dead_reckoning"' not in page


def _not_blank(png: Path) -> None:
    from PIL import Image

    img = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert img.std() > 10, "the screenshot is blank"


def test_run_page_in_headless_chromium(chromium, run_dir, tmp_path):
    page = load_page(chromium, run_dir / "report.html", tmp_path)
    assert page.console == []
    # Plotly drew every figure (one plot container each, SVG layers inside)
    assert page.dom.count('class="plot-container plotly"') == 3
    assert page.dom.count('class="main-svg"') >= 6
    assert page.dom.count('class="scatterlayer') >= 3
    _not_blank(page.screenshot)


def test_campaign_page_in_headless_chromium(chromium, campaign_dir, tmp_path):
    html = (campaign_dir / "report.html").read_text()
    _self_contained(html)
    assert "| with_terrain | ekf | 2 |" in (campaign_dir / "table.md").read_text()
    assert "<td>with_terrain</td><td>ekf</td><td>2</td>" in html
    assert (campaign_dir / "rmse_summary.png").is_file()
    page = load_page(chromium, campaign_dir / "report.html", tmp_path)
    assert page.console == []
    # one per-run figure per variant and the box plots
    assert page.dom.count('class="plot-container plotly"') == 3
    assert page.dom.count('class="boxlayer') >= 1
    _not_blank(page.screenshot)


def test_the_browser_check_sees_console_errors(chromium, tmp_path):
    """The check above can fail: a page with an error is caught."""
    bad = tmp_path / "bad.html"
    bad.write_text("<html><body><p>x</p><script>undefinedFunction();</script></body></html>")
    page = load_page(chromium, bad, tmp_path)
    assert any("undefinedFunction" in line for line in page.console)

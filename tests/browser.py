"""A real headless Chromium for the HTML report tests (Debian's ``chromium`` package).

:func:`find_chromium` returns the browser, installing it with ``apt-get`` when it is missing and
we are root (``make test`` does the same first); the tests skip with the reason otherwise.
:func:`load_page` opens a file with no network, no GPU and a throw-away profile, and returns
the DOM after the scripts ran, the console messages the page produced (Chromium logs every
``console.*`` call and uncaught error as ``INFO:CONSOLE`` on stderr) and a screenshot.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         "--disable-default-apps", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=15000")


def find_chromium() -> tuple[str | None, str]:
    """``(path, "")`` or ``(None, why not)``."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path, ""
    if os.name != "posix" or os.geteuid() != 0 or not shutil.which("apt-get"):
        return None, "chromium is not installed and we are not root to 'apt-get install chromium'"
    try:
        subprocess.run(["apt-get", "install", "-y", "-q", "chromium"], check=True,
                       capture_output=True, timeout=900)
    except (subprocess.SubprocessError, OSError) as exc:
        return None, f"'apt-get install -y chromium' failed ({exc})"
    path = shutil.which("chromium")
    return (path, "") if path else (None, "apt-get installed no 'chromium' executable")


@dataclass
class Page:
    dom: str
    console: list[str]
    screenshot: Path


def load_page(chromium: str, page: Path, workdir: Path, size=(1200, 2600)) -> Page:
    url = Path(page).resolve().as_uri()
    common = [chromium, *FLAGS, f"--window-size={size[0]},{size[1]}"]
    dom = subprocess.run([*common, f"--user-data-dir={workdir / 'profile-dom'}", "--dump-dom",
                          url], capture_output=True, text=True, timeout=180)
    shot = workdir / "screenshot.png"
    pic = subprocess.run([*common, f"--user-data-dir={workdir / 'profile-shot'}",
                          f"--screenshot={shot}", url], capture_output=True, text=True,
                         timeout=180)
    console = [line for out in (dom.stderr, pic.stderr) for line in out.splitlines()
               if ":CONSOLE" in line]
    return Page(dom.stdout, console, shot)

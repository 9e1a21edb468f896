"""Start-up and exit of the command line: what a short ``uwcosim run`` costs before and after
its work.

Measured in one run, side by side (the machine is shared: compare the rows, not the seconds):

1. the wall time and the CPU time (user + system of the command's processes) of whole
   commands, median of ``--repeat`` runs with warm caches (the FMUs built, the Numba kernels in
   their on-disk cache, the modules' bytecode written, the OS file cache warm after one untimed
   run of each): ``python -c pass`` (the interpreter alone), ``uwcosim --version``,
   ``uwcosim run SCENARIO --set run.duration=10 --no-figures`` for the shipped scenarios
   (``lost_measurements``: Kalman filters only, no compiled kernel; ``tan_dead_reckoning`` and
   ``tan_terrain``: six filters, four of them with compiled kernels), each also with
   ``UWCOSIM_FAST_EXIT=0`` (the interpreter's normal teardown after the last line); two floors
   of a terrain start: a command that only imports the third-party modules (neither the
   standard library's nor uwcosim's) that ``run tan_terrain`` imports, without and with Numba
   (what any start of that run costs before uwcosim's own modules, its kernels and its work);
   with ``--compare REV`` (a git revision, e.g. ``main``: its ``git archive`` unpacked into a
   folder of the temporary directory that is kept, so that its Numba cache stays warm, with
   this checkout's FMUs copied into it; or ``--compare SRC``, an unpacked older source tree
   with its FMUs in ``SRC/fmus``) the same commands run from it (``PYTHONPATH=SRC``) in the same
   loop, interleaved with this tree's: the before/after ratios. The first run of a revision
   compiles its kernels (a few minutes, untimed);
2. the import time of a 10-step ``lost_measurements`` and ``tan_terrain`` run (``python -X
   importtime``), the self time of every module summed by top-level package (numba, scipy,
   casadi, ...): where the fixed cost of a run is; which of numba, matplotlib and pandas a run
   imports; and how many compiled kernels (specializations) ``tan_terrain`` loads from Numba's
   cache (``NUMBA_DEBUG_CACHE``); Numba's share of that run in one process (its import, its
   kernel loads), and the floor of a terrain start: the third-party imports with Numba plus
   the kernel loads.

The timed commands run without ``PYTHONDONTWRITEBYTECODE`` (if the shell sets it): with it, every
start compiles the package's modules from source (0.2-0.3 s), which a user's installation does
not. Goal (issue 22): ``uwcosim run --no-figures`` of a 10-step scenario <= 1.0 s wall on a
quiet 2-core machine with warm caches; no Numba import without compiled filters; no matplotlib
without figures. Run: ``.venv/bin/python benchmarks/bench_startup.py [--repeat 5]
[--compare main]``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UWCOSIM = [sys.executable, "-m", "uwcosim"]
SCENARIOS = ("lost_measurements", "tan_dead_reckoning", "tan_terrain")
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """``(wall s, CPU s)`` of ``cmd``; the CPU time of every process it waited for included."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def run_cmd(scenario: str, out: Path) -> list[str]:
    return [*UWCOSIM, "-q", "run", scenario, "--set", "run.duration=10", "--no-figures",
            "--out", str(out), "--force"]


def import_trace(cmd: list[str]) -> list[tuple[str, float]]:
    """``(module, self import time s)`` of every module the command imports, in the order they
    finished importing (``python -X importtime``)."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *cmd[1:]], check=True,
                          capture_output=True, text=True, cwd=ROOT, env=ENV)
    out = []
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        self_us, _, name = line[len("import time:"):].split("|")
        out.append((name.strip(), int(self_us) / 1e6))
    return out


def import_breakdown(cmd: list[str]) -> tuple[dict[str, float], set[str]]:
    """Self import time (s) by top-level package, and the top-level packages imported."""
    by_top: dict[str, float] = defaultdict(float)
    for name, self_s in import_trace(cmd):
        by_top[name.split(".")[0]] += self_s
    return dict(by_top), set(by_top)


def third_party_modules(cmd: list[str]) -> list[str]:
    """The modules the command imports that are neither the standard library's nor uwcosim's,
    Numba's or llvmlite's, in the order they finished importing."""
    own = {"uwcosim", "numba", "llvmlite", "__main__"}
    return [name for name, _ in import_trace(cmd)
            if (top := name.split(".")[0]) not in own and top not in sys.stdlib_module_names
            and not top.startswith("_")]


def import_cmd(modules: list[str]) -> list[str]:
    """A command that imports ``modules`` (the ones that import on their own) and exits."""
    code = (f"import importlib\nfor m in {modules!r}:\n    try:\n"
            "        importlib.import_module(m)\n    except Exception:\n        pass\n")
    return [sys.executable, "-c", code]


def cache_package(path: Path) -> str:
    """The package of a Numba cache file: Numba names its folder ``<package>_<digest>`` in the
    kernel cache, which ``core.jit`` always sets (``kernel_cache_dir`` or ``NUMBA_CACHE_DIR``)."""
    return path.parent.name.rsplit("_", 1)[0]


def kernels_loaded(cmd: list[str]) -> dict[str, list[int]]:
    """The compiled specializations the command loads from Numba's cache: ``{kernel module:
    [count, bytes]}`` (a cache file holds the kernel's object code and the bitcode of it and
    of every kernel it calls, which Numba parses at the load)."""
    proc = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT,
                          env={**ENV, "NUMBA_DEBUG_CACHE": "1"})
    out: dict[str, list[int]] = defaultdict(lambda: [0, 0])
    for line in proc.stdout.splitlines():
        if "data loaded from" in line:
            path = Path(line.split("'")[1])
            module = f"{cache_package(path)}.{path.name.split('.')[0]}"
            out[module][0] += 1
            out[module][1] += path.stat().st_size
    return dict(out)


#: ``tan_terrain`` in one process with Numba imported first: Numba's import, the time in its
#: compiler lock (every kernel loaded from the cache, the first load's set-up of its target
#: context included; :func:`numba.core.event.install_timer`) and the whole run
NUMBA_PROBE = """
import json, sys, time
t0 = time.perf_counter()
import numba
from numba.core import event
t1 = time.perf_counter()
from uwcosim.cli import main
held = []
with event.install_timer("numba:compiler_lock", held.append):
    main(sys.argv[1:])
t2 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "loads": sum(held), "total": t2 - t0}))
"""


#: the map and the filters' model of ``tan_terrain`` built in a fresh process (CPU s after the
#: imports): the start-up work that scales with the map (synthesis, spline coefficients,
#: FastTerrain's table, the CasADi model), without Numba
MODEL_PROBE = """
import sys, time
from uwcosim.run.factory import build_model, scenario_map
from uwcosim.scenario.load import load_scenario
loaded = load_scenario(sys.argv[1])
t0 = time.process_time()
model = build_model(loaded, scenario_map(loaded))
print(time.process_time() - t0)
"""


def model_setup(env: dict, cwd: Path) -> float:
    """:data:`MODEL_PROBE` of ``tan_terrain`` in the tree of ``env``/``cwd`` (CPU s)."""
    proc = subprocess.run([sys.executable, "-c", MODEL_PROBE, "scenarios/tan_terrain.toml"],
                          check=True, capture_output=True, text=True, cwd=cwd, env=env)
    return float(proc.stdout.strip().splitlines()[-1])


def numba_share(cmd: list[str]) -> dict[str, float]:
    """:data:`NUMBA_PROBE` of a run command: seconds of Numba's import, of its kernel loads,
    and of the whole process after the interpreter's own start."""
    proc = subprocess.run([sys.executable, "-c", NUMBA_PROBE, *cmd[3:]], check=True,
                          capture_output=True, text=True, cwd=ROOT, env=ENV)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def source_tree(spec: str) -> Path:
    """The older tree of ``--compare``: a folder as given, or a git revision's archive."""
    if Path(spec).is_dir():
        return Path(spec).resolve()
    sha = subprocess.run(["git", "rev-parse", spec], check=True, capture_output=True,
                         text=True, cwd=ROOT).stdout.strip()
    src = Path(tempfile.gettempdir()) / f"uwcosim_bench_startup_{sha[:12]}"
    if not (src / "uwcosim").is_dir():
        tmp = Path(tempfile.mkdtemp(prefix=src.name + "_", dir=src.parent))
        archive = subprocess.run(["git", "archive", sha], check=True, capture_output=True,
                                 cwd=ROOT).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(tmp, filter="data")
        shutil.copytree(ROOT / "fmus", tmp / "fmus", dirs_exist_ok=True)
        tmp.rename(src)
    changed = subprocess.run(["git", "diff", "--quiet", sha, "--", "models", "uwcosim/fmu"],
                             cwd=ROOT).returncode
    if changed:
        print(f"note: the FMU sources differ between {spec} and this tree; {src}/fmus holds "
              f"this tree's FMUs", file=sys.stderr)
    return src


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per command")
    ap.add_argument("--compare", default=None, metavar="REV|SRC",
                    help="a git revision or an older source tree to time side by side")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_startup_"))
    slow_exit = {**ENV, "UWCOSIM_FAST_EXIT": "0"}
    rows = [("python -c pass", [sys.executable, "-c", "pass"], ENV, ROOT),
            ("uwcosim --version", [*UWCOSIM, "--version"], ENV, ROOT)]
    for s in SCENARIOS:
        rows.append((f"run {s} (10 steps, --no-figures)", run_cmd(s, tmp / s), ENV, ROOT))
        rows.append((f"run {s}, normal interpreter exit", run_cmd(s, tmp / s), slow_exit, ROOT))
    # the floor of a terrain start: what it imports besides uwcosim, without and with Numba
    libs = third_party_modules(run_cmd("tan_terrain", tmp / "floor"))
    rows.append(("imports of run tan_terrain alone: third-party, no Numba", import_cmd(libs),
                 ENV, ROOT))
    rows.append(("imports of run tan_terrain alone: third-party and Numba",
                 import_cmd([*libs, "numba"]), ENV, ROOT))
    if args.compare:
        src = source_tree(args.compare)
        old = {**ENV, "PYTHONPATH": str(src)}
        rows.append((f"before ({args.compare}): uwcosim --version", [*UWCOSIM, "--version"],
                     old, src))
        for s in SCENARIOS:
            rows.append((f"before ({args.compare}): run {s} (10 steps, --no-figures)",
                         run_cmd(str(src / "scenarios" / f"{s}.toml"), tmp / f"before_{s}"),
                         old, src))
    for _, cmd, env, cwd in rows:  # warm: FMUs, kernel cache, bytecode, file cache
        timed(cmd, env, cwd)
    times: dict[str, list[tuple[float, float]]] = {label: [] for label, *_ in rows}
    for _ in range(args.repeat):  # interleaved: the load of the machine hits every row alike
        for label, cmd, env, cwd in rows:
            times[label].append(timed(cmd, env, cwd))
    print(f"## whole commands (median of {args.repeat}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end)\n")
    print("| command | median wall (s) | min wall (s) | median CPU (s) |\n|---|---|---|---|")
    for label, ts in times.items():
        walls, cpus = [w for w, _ in ts], [c for _, c in ts]
        print(f"| {label} | {statistics.median(walls):.2f} | {min(walls):.2f} | "
              f"{statistics.median(cpus):.2f} |")
    trees = [("this tree", ENV, ROOT)] + ([(f"before ({args.compare})", old, src)]
                                           if args.compare else [])
    setup: dict[str, list[float]] = {label: [] for label, _, _ in trees}
    for _ in range(args.repeat):
        for label, env, cwd in trees:
            setup[label].append(model_setup(env, cwd))
    print("\nmap and model of tan_terrain built in a fresh process (median CPU s): " +
          ", ".join(f"{label} {statistics.median(ts):.3f}" for label, ts in setup.items()))
    if args.compare:
        print("\nafter / before (median wall, median CPU):")
        for s in SCENARIOS:
            new = times[f"run {s} (10 steps, --no-figures)"]
            ref = times[f"before ({args.compare}): run {s} (10 steps, --no-figures)"]
            wall = statistics.median(w for w, _ in new) / statistics.median(w for w, _ in ref)
            cpu = statistics.median(c for _, c in new) / statistics.median(c for _, c in ref)
            print(f"- {s}: {wall:.2f}, {cpu:.2f}")

    for s in ("lost_measurements", "tan_terrain"):
        by_top, seen = import_breakdown(run_cmd(s, tmp / f"imports_{s}"))
        total = sum(by_top.values())
        print(f"\n## imports of `run {s}` (10 steps): {total:.2f} s in all\n")
        print("| package | self import time (s) | share |\n|---|---|---|")
        for top, t in sorted(by_top.items(), key=lambda kv: -kv[1])[:12]:
            print(f"| {top} | {t:.3f} | {t / total:.0%} |")
        print("\n" + ", ".join(f"{lib} imported: {'yes' if lib in seen else 'no'}"
                               for lib in ("numba", "matplotlib", "pandas")))
    loads = kernels_loaded(run_cmd("tan_terrain", tmp / "kernels"))
    n, size = (sum(v[i] for v in loads.values()) for i in (0, 1))
    print(f"\n`run tan_terrain` loads {n} compiled kernel specializations ({size / 1e6:.1f} MB) "
          f"from Numba's cache:\n\n| kernel module | loaded | MB |\n|---|---|---|")
    for module, (k, b) in sorted(loads.items(), key=lambda kv: -kv[1][1]):
        print(f"| {module} | {k} | {b / 1e6:.2f} |")
    shares = [numba_share(run_cmd("tan_terrain", tmp / "probe")) for _ in range(args.repeat)]
    med = {k: statistics.median(sh[k] for sh in shares) for k in shares[0]}
    print(f"\n## Numba's share of `run tan_terrain` in one process (median of {args.repeat}, "
          f"s)\n\n| part | s |\n|---|---|\n| import numba | {med['import']:.2f} |\n"
          f"| kernel loads from the cache (target set-up included) | {med['loads']:.2f} |\n"

          f"| everything else after the interpreter's start | "
          f"{med['total'] - med['import'] - med['loads']:.2f} |\n"
          f"| whole run in process | {med['total']:.2f} |")
    floor = statistics.median(w for w, _ in times[
        "imports of run tan_terrain alone: third-party and Numba"]) + med["loads"]
    print(f"\nfloor of a 10-step `run tan_terrain` with Numba's cached kernels: the third-party "
          f"imports with Numba (whole command, above) plus the kernel loads = {floor:.2f} s, "
          f"before any uwcosim module or work (goal of issue 22: <= 1.0 s)")
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

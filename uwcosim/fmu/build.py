"""Build the project's FMUs from the CasADi equations (``python -m uwcosim.fmu.build``).

For every (model, FMI version) the build generates the CasADi C code of the equations
(``uwc_eqs.c``), the configuration header of the C template (``uwc_config.h``) and
``modelDescription.xml``, compiles them with the templates in ``uwcosim/fmu/templates`` into
one shared library (gcc, ``-shared -fPIC -O2``; ``$CC`` overrides the compiler) and zips the
FMU. Every archive holds both interfaces, ModelExchange and CoSimulation.

Naming scheme (``out_dir`` defaults to ``fmus/``; :func:`uwcosim.core.paths.fmu_file_name`):

- ``<Model>.fmu``       FMI 3.0 (the default FMUs used by scenarios)
- ``<Model>_fmi2.fmu``  FMI 2.0

A user's models go through the same tooling: :func:`register_specs` imports
``package.module:NAME`` (a :class:`~uwcosim.fmu.specs.ModelSpec`, a list of them, or a function
returning either; the current folder in front of ``sys.path`` for the import) and adds them to
the models of this process (``uwcosim fmu build --spec current_nav.fmus:specs``).

Builds are incremental: a SHA-256 over the generated C code, the templates, the XML, the
compiler flags and the resources is stored in the archive (``extra/uwcosim/build.json``) and
an archive whose hash is unchanged (and which has a binary for this platform) is skipped. The
instantiation token / GUID is derived from the same hash.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.core.paths import fmu_file_name
from uwcosim.core.plugins import describe_error, import_object
from uwcosim.fmu.codegen import GUID_PLACEHOLDER, config_header, equations_c
from uwcosim.fmu.model_description import generation_tool, model_description
from uwcosim.fmu.specs import DEFAULT_MAP_FILE, DEFAULT_MAP_SEED, MODELS, ModelSpec, get_spec
from uwcosim.models.terrain import synthetic_bathymetry

log = logging.getLogger(__name__)

FMI_VERSIONS = ("3.0", "2.0")
TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"
TEMPLATE_FILES = ("uwc_model.h", "uwc_model.c", "uwc_map.h", "uwc_map.c", "uwc_fmi2.c",
                  "uwc_fmi3.c", "uwc_fmi_common.h")
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden", "-ffp-contract=off",
          "-DCASADI_SYMBOL_EXPORT=")
BUILD_INFO = "extra/uwcosim/build.json"
BUILD_FORMAT = 1
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def normalize_version(fmi_version: str | int | float) -> str:
    """``2``, ``"2"``, ``"2.0"`` -> ``"2.0"``; likewise for 3 (FMUError otherwise)."""
    text = str(fmi_version).strip()
    for v in FMI_VERSIONS:
        if text in (v, v[0]):
            return v
    raise FMUError(f"unsupported FMI version {fmi_version!r} (valid: 2.0, 3.0)")


def archive_name(model: str, fmi_version: str | int = "3.0") -> str:
    """File name of the FMU of ``model``: ``<Model>.fmu`` (FMI 3.0), ``<Model>_fmi2.fmu``
    (:func:`uwcosim.core.paths.fmu_file_name`)."""
    return fmu_file_name(model, normalize_version(fmi_version) == "3.0")


def register_specs(type_strings: list[str] | tuple[str, ...],
                   search: tuple[Path, ...] = ()) -> list[str]:
    """Import each ``package.module:NAME`` (a ModelSpec, a list of them, or a function
    returning either) and add its specs to the builder's models for this process; their
    names. FMUError (one line) for an import error, something that is not a spec, or a name
    the project's models already have."""
    names = []
    for text in type_strings:
        try:
            obj, _ = import_object(text, search or (Path.cwd(),))
            found = obj() if callable(obj) and not isinstance(obj, ModelSpec) else obj
        except ScenarioError as exc:
            raise FMUError(f"--spec {exc}") from None
        except Exception as exc:  # noqa: BLE001 - the user's function: its error in one line
            raise FMUError(f"--spec {text!r}: {describe_error(exc)}") from None
        found = [found] if isinstance(found, ModelSpec) else found
        if not isinstance(found, list | tuple) or not found \
                or not all(isinstance(s, ModelSpec) for s in found):
            raise FMUError(f"--spec {text!r}: expected a uwcosim.fmu.specs.ModelSpec, a list "
                           f"of them or a function returning either")
        for spec in found:
            if spec.name in _PROJECT_MODELS:
                raise FMUError(f"--spec {text!r}: model name {spec.name!r} is one of the "
                               f"project's FMUs (rename it)")

            def factory(spec: ModelSpec = spec) -> ModelSpec:
                return spec

            MODELS[spec.name] = factory
            names.append(spec.name)
    return names


def targets(names: list[str] | tuple[str, ...] | None = None) -> list[tuple[str, str]]:
    """(model, FMI version) pairs for model names (both versions) or archive stems."""
    if names is None:
        return [(m, v) for m in MODELS for v in FMI_VERSIONS]
    stems = {Path(archive_name(m, v)).stem: (m, v) for m in MODELS for v in FMI_VERSIONS}
    out: list[tuple[str, str]] = []
    for name in names:
        key = name[:-4] if name.endswith(".fmu") else name
        found = [(key, v) for v in FMI_VERSIONS] if key in MODELS else [stems.get(key)]
        if found == [None]:
            valid = ", ".join(list(MODELS) + sorted(stems))
            raise FMUError(f"unknown FMU {name!r} (valid: {valid})")
        out += [t for t in found if t not in out]
    return out


def binary_dir(fmi_version: str) -> str:
    """Folder of this platform's binary inside an FMU (``binaries/linux64`` for FMI 2.0,
    ``binaries/x86_64-linux`` for FMI 3.0)."""
    import fmpy  # lazy: as in library_name

    plat = fmpy.platform_tuple if normalize_version(fmi_version) == "3.0" else fmpy.platform
    return f"binaries/{plat}"


def library_name(model: str) -> str:
    """The file name of ``model``'s shared library on this platform (``<Model>.so``)."""
    # lazy: fmpy only to build (uwcosim list and demo import this module for its names)
    import fmpy

    return f"{model}{fmpy.sharedLibraryExtension}"


def _fmi_headers() -> Path:
    import fmpy  # lazy: as in library_name

    path = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (path / "fmi3Functions.h").is_file():
        raise FMUError(f"{path}: FMI headers not found (fmpy installation incomplete)")
    return path


@lru_cache(maxsize=1)
def default_map_bytes() -> bytes:
    """The DepthSounder's default map: ``synthetic_bathymetry(seed=7)`` as UWCBATH1 bytes."""
    with tempfile.TemporaryDirectory(prefix="uwcosim-map-") as tmp:
        path = synthetic_bathymetry(DEFAULT_MAP_SEED).write_coefficients(Path(tmp) / "map")
        return path.read_bytes()


_RESOURCES = {DEFAULT_MAP_FILE: default_map_bytes}
#: the project's own models (a user's spec may not take their names)
_PROJECT_MODELS = frozenset(MODELS)


@dataclass
class Sources:
    """Everything generated for one (model, FMI version), before compilation."""

    model: str
    fmi_version: str
    equations: str
    config: str
    xml: str
    digest: str
    guid: str
    resources: dict[str, bytes] = field(default_factory=dict)
    hooks: Path | None = None  # C source of a test model's hooks


def prepare(model: str, fmi_version: str | int) -> Sources:
    """Generate the sources of one FMU and their hash (no compilation)."""
    version = normalize_version(fmi_version)
    spec = get_spec(model)
    eqs = equations_c(spec)
    resources = {name: _RESOURCES[name]() for name in spec.resources}
    h = hashlib.sha256()
    parts = [str(BUILD_FORMAT), version, " ".join(CFLAGS), eqs, config_header(spec),
             model_description(spec, version, GUID_PLACEHOLDER)]
    for part in parts:
        h.update(part.encode() + b"\0")
    for name in TEMPLATE_FILES:
        h.update(name.encode() + b"\0" + (TEMPLATE_DIR / name).read_bytes() + b"\0")
    for name, data in sorted(resources.items()):
        h.update(name.encode() + b"\0" + hashlib.sha256(data).digest())
    if spec.hooks is not None:
        h.update(b"hooks\0" + Path(spec.hooks).read_bytes() + b"\0")
    guid = "{" + str(uuid.UUID(bytes=h.digest()[:16], version=5)) + "}"
    return Sources(model, version, eqs, config_header(spec, guid),
                   model_description(spec, version, guid), h.hexdigest(), guid, resources,
                   spec.hooks)


def compile_shared(sources: list[Path], out: Path, include_dirs: list[Path] = (),
                   flags: tuple[str, ...] = CFLAGS, label: str = "") -> Path:
    """Compile C ``sources`` into the shared library ``out`` (FMUError with the compiler's
    first error line on failure)."""
    cc = os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        raise FMUError(f"C compiler {cc!r} not found (install gcc or set CC)")
    cmd = [cc, *flags, *[f"-I{d}" for d in include_dirs], *map(str, sources), "-o", str(out),
           "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
        errors = [ln for ln in lines if re.search(r"\b(error|Error|ERROR)\b:", ln)]
        first = (errors or lines or [f"exit status {proc.returncode}"])[0]
        raise FMUError(f"{label or out.name}: compilation failed: {first}")
    return out


def build_map_kernel(out_path: str | Path) -> Path:
    """Compile the terrain kernel alone (``uwc_map.c``) as a shared library with exported
    ``uwc_map_load/free/extent/inside/depth`` (for tests and tools)."""
    out_path = Path(out_path)
    flags = tuple(f for f in CFLAGS if f != "-fvisibility=hidden")
    return compile_shared([TEMPLATE_DIR / "uwc_map.c"], out_path, [TEMPLATE_DIR], flags,
                          "uwc_map kernel")


def _zip_write(zf: zipfile.ZipFile, name: str, data: bytes, mode: int = 0o644) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = mode << 16
    zf.writestr(info, data)


def _package(src: Sources, binary: Path, out_path: Path) -> None:
    info = {"format": BUILD_FORMAT, "model": src.model, "fmi_version": src.fmi_version,
            "source_hash": src.digest, "guid": src.guid, "generator": generation_tool()}
    tmp = out_path.with_name(f".{out_path.name}.{os.getpid()}.tmp")
    with zipfile.ZipFile(tmp, "w") as zf:
        _zip_write(zf, "modelDescription.xml", src.xml.encode())
        lib = f"{binary_dir(src.fmi_version)}/{library_name(src.model)}"
        _zip_write(zf, lib, binary.read_bytes(), 0o755)
        for name, data in sorted(src.resources.items()):
            _zip_write(zf, f"resources/{name}", data)
        _zip_write(zf, BUILD_INFO, json.dumps(info, indent=2).encode())
    os.replace(tmp, out_path)


def _build(src: Sources, out_path: Path) -> Path:
    """Compile and package one FMU; the build folder is kept (and named) on failure."""
    out_path.parent.mkdir(parents=True, exist_ok=True)
    build_root = out_path.parent / ".build"
    build_root.mkdir(exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"{out_path.stem}-", dir=build_root))
    (work / "uwc_eqs.c").write_text(src.equations)
    (work / "uwc_config.h").write_text(src.config)
    (work / "modelDescription.xml").write_text(src.xml)
    wrapper = "uwc_fmi3.c" if src.fmi_version == "3.0" else "uwc_fmi2.c"
    sources = [work / "uwc_eqs.c"] + [TEMPLATE_DIR / n for n in ("uwc_model.c", "uwc_map.c",
                                                                 wrapper)]
    if src.hooks is not None:
        sources.append(Path(src.hooks))
    binary = work / library_name(src.model)
    try:
        compile_shared(sources, binary, [work, TEMPLATE_DIR, _fmi_headers()],
                       label=f"{out_path.name} (sources kept in {work})")
        _package(src, binary, out_path)
    except FMUError:
        raise
    except OSError as exc:
        raise FMUError(f"{out_path}: cannot write the FMU ({exc})") from None
    shutil.rmtree(work, ignore_errors=True)
    log.info("built %s", out_path)
    return out_path


def build_info(path: str | Path) -> dict | None:
    """The build record stored in an archive (None if absent or unreadable)."""
    try:
        with zipfile.ZipFile(path) as zf:
            return json.loads(zf.read(BUILD_INFO))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None


def is_up_to_date(path: Path, src: Sources) -> bool:
    """True if ``path`` was built from exactly ``src`` and has this platform's binary."""
    info = build_info(path)
    if info is None or info.get("source_hash") != src.digest:
        return False
    lib = f"{binary_dir(src.fmi_version)}/{library_name(src.model)}"
    try:
        with zipfile.ZipFile(path) as zf:
            return lib in zf.namelist() and "modelDescription.xml" in zf.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def build_fmu(name: str, fmi_version: str | int, out_path: str | Path) -> Path:
    """Build the FMU of model ``name`` for ``fmi_version`` (2 or 3) into ``out_path``
    (always rebuilds)."""
    return _build(prepare(name, fmi_version), Path(out_path))


def build_fmus(out_dir: str | Path = "fmus", names: list[str] | None = None,
               force: bool = False) -> list[Path]:
    """Build the FMUs ``names`` (model names -> both FMI versions, or archive stems such as
    ``"AUVKinematics_fmi2"``; default: all) into ``out_dir``; skip up-to-date archives
    unless ``force``. Returns the archive paths in build order."""
    out_dir = Path(out_dir)
    wanted = targets(names)
    todo: list[tuple[Sources, Path]] = []
    for model, version in wanted:
        src = prepare(model, version)
        path = out_dir / archive_name(model, version)
        if force or not is_up_to_date(path, src):
            todo.append((src, path))
        else:
            log.info("%s is up to date", path)
    if todo:
        with ThreadPoolExecutor(max_workers=max(1, min(len(todo), os.cpu_count() or 1))) as ex:
            list(ex.map(lambda job: _build(*job), todo))
    return [out_dir / archive_name(m, v) for m, v in wanted]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m uwcosim.fmu.build", description=__doc__
                                     .split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="models or archive stems (default: all)")
    parser.add_argument("-o", "--out-dir", default="fmus", help="output folder (fmus)")
    parser.add_argument("-f", "--force", action="store_true", help="rebuild everything")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        paths = build_fmus(args.out_dir, args.names or None, args.force)
    except FMUError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    print("\n".join(str(p) for p in paths))
    return 0


if __name__ == "__main__":
    sys.exit(main())

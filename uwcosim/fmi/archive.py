"""The FMU archive: one validator for the master and ``uwcosim fmu info`` / ``fmu check``.

:func:`archive_problems` finds what makes a file unusable as an FMU before anything is loaded:
missing file, not a zip archive, a member whose compressed data is corrupt (bad CRC or bad
deflate stream: every member is read once), a member name that is absolute or climbs out of
the folder with ``..`` (it would be extracted outside the FMU's folder), an unpacked size
(the members' sizes in the archive's directory, checked before anything is inflated: a zip
bomb) above :data:`MAX_UNPACKED_MB` MiB (the scenario key ``run.fmu_max_unpacked_mb``, applied
with :func:`unpacked_limit` while its FMUs and SSP are opened; else the environment variable
``UWCOSIM_FMU_MAX_UNPACKED_MB``), no ``modelDescription.xml``. :func:`archive_size_problem` is
that check alone (an ``.ssp`` archive's, before a member is read). :func:`binary_problems`
checks the shared library of this platform for each interface (FMI 2 ``binaries/linux64``,
FMI 3 ``binaries/x86_64-linux``).
:func:`open_archive` checks the archive and reads its model description, :func:`open_description`
checks the binaries too; both raise one-line :class:`~uwcosim.core.errors.FMUError` s.
:func:`unzip` extracts what a run needs of a checked archive: ``modelDescription.xml``, this
platform's binaries and ``resources/`` (not the documentation, sources or other platforms).
:func:`library_problems` loads each binary in a separate process (a library that cannot be
loaded, or crashes when loaded, is reported, not suffered) and checks that it exports the FMI
functions its interfaces need (``uwcosim fmu check``). A missing FMU of the project's own
(:func:`uwcosim.core.paths.is_project_fmu`) is reported with the hint to build it.

A folder that holds an unzipped FMU (``modelDescription.xml`` at its top) is accepted too.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription

from uwcosim.core import scratch
from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.core.paths import is_project_fmu
from uwcosim.fmi.description_errors import explain

INTERFACE_NAMES = {"cs": "co-simulation", "me": "model exchange"}
MIB = 1 << 20
#: the default limit of an FMU archive's unpacked size (MiB), and the variable that sets it
MAX_UNPACKED_MB = 512
MAX_UNPACKED_ENV = "UWCOSIM_FMU_MAX_UNPACKED_MB"
#: the scenario key that sets it for a scenario's FMUs and SSP (:func:`unpacked_limit`)
MAX_UNPACKED_KEY = "run.fmu_max_unpacked_mb"
_limit: list[float] = []  # the limits (MiB) of the unpacked_limit blocks this process is in
#: what "FMU not found" adds for one of the project's own FMUs (:func:`is_project_fmu`)
BUILD_HINT = " (build the project's FMUs with 'uwcosim fmu build')"


def sha256_file(path: Path) -> str:
    """SHA-256 of a file (hex), read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@contextmanager
def unpacked_limit(mb: float | None) -> Iterator[None]:
    """Inside the block, the unpacked-size limit is ``mb`` MiB (the scenario key
    :data:`MAX_UNPACKED_KEY`); None: the environment variable's or the default, as outside."""
    if mb is None:
        yield
        return
    _limit.append(float(mb))
    try:
        yield
    finally:
        _limit.pop()


def limit_source() -> str:
    """What sets the limit in force: the scenario key or the environment variable."""
    return MAX_UNPACKED_KEY if _limit else MAX_UNPACKED_ENV


def max_unpacked_bytes() -> int:
    """The limit of an FMU archive's unpacked size in bytes: that of :func:`unpacked_limit`,
    else :data:`MAX_UNPACKED_MB` MiB or the environment variable :data:`MAX_UNPACKED_ENV`
    (MiB)."""
    if _limit:
        return int(_limit[-1] * MIB)
    text = os.environ.get(MAX_UNPACKED_ENV, "").strip()
    if not text:
        return MAX_UNPACKED_MB * MIB
    try:
        mb = float(text)
    except ValueError:
        mb = float("nan")
    if not mb > 0 or mb == float("inf"):
        raise ScenarioError(f"{MAX_UNPACKED_ENV}={text!r}: expected a positive number of MiB "
                            f"(the limit of an FMU's unpacked size)")
    return int(mb * MIB)


def _bad_member_name(name: str) -> bool:
    if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
        return True
    return ".." in PurePosixPath(name.replace("\\", "/")).parts


def member_names(path: Path) -> list[str]:
    """The archive's member names (or, for a folder, its files relative to it)."""
    path = Path(path)
    if path.is_dir():
        return [p.relative_to(path).as_posix() for p in path.rglob("*") if p.is_file()]
    with zipfile.ZipFile(path) as zf:
        return zf.namelist()


def archive_size_problem(path: Path, zf: zipfile.ZipFile, what: str) -> str | None:
    """The one line for an archive whose members' sizes (in its directory: nothing inflated)
    add up to more than :func:`max_unpacked_bytes`, else None."""
    cap = max_unpacked_bytes()
    size = sum(info.file_size for info in zf.infolist())
    if size <= cap:
        return None
    return (f"{path}: {what} unpacks to {size / MIB:.0f} MiB, more than the limit of "
            f"{cap / MIB:g} MiB ({limit_source()})")


def archive_problems(path: str | Path) -> list[str]:
    """Problems that make ``path`` unusable as an FMU archive (empty list: readable)."""
    path = Path(path)
    if not path.exists():
        return [f"{path}: FMU not found{BUILD_HINT if is_project_fmu(path) else ''}"]
    if path.is_dir():
        return [] if (path / "modelDescription.xml").is_file() else [
            f"{path}: not an FMU (folder without modelDescription.xml)"]
    try:
        with zipfile.ZipFile(path) as zf:
            names = zf.namelist()
            bad = [n for n in names if _bad_member_name(n)]
            if bad:
                return [f"{path}: unsafe FMU archive (member name {bad[0]!r} is absolute or "
                        f"contains '..')"]
            too_big = archive_size_problem(path, zf, "FMU archive")
            if too_big:  # before anything is inflated (a zip bomb)
                return [too_big]
            for info in zf.infolist():  # inflate every member and check its CRC
                try:
                    with zf.open(info) as fh:
                        while fh.read(1 << 20):
                            pass
                except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
                    return [f"{path}: corrupt FMU archive (member {info.filename!r}: {exc})"]
    except zipfile.BadZipFile as exc:
        return [f"{path}: not a valid FMU archive ({exc})"]
    except (OSError, ValueError, NotImplementedError) as exc:
        return [f"{path}: cannot read the FMU archive ({type(exc).__name__}: {exc})"]
    if "modelDescription.xml" not in names:
        return [f"{path}: not an FMU (no modelDescription.xml in the archive)"]
    return []


def read_model(path: str | Path) -> ModelDescription:
    """The model description of an archive :func:`archive_problems` found readable."""
    # lazy: fmpy (0.1 s) once an FMU is opened, not when the master's modules are imported
    from fmpy.model_description import read_model_description

    why = xml_problem(path)
    if why:
        raise FMUError(f"{path}: invalid modelDescription.xml: {why}")
    try:
        return read_model_description(str(path), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions for bad XML
        why = explain(_description_bytes(path), exc)  # in the file's terms, not Python's
        raise FMUError(f"{path}: invalid modelDescription.xml: {why}") from None


def _description_bytes(path: str | Path) -> bytes:
    if Path(path).is_dir():  # an unzipped FMU folder
        return (Path(path) / "modelDescription.xml").read_bytes()
    with zipfile.ZipFile(path) as zf:
        return zf.read("modelDescription.xml")


def xml_problem(path: str | Path) -> str | None:
    """What is wrong with the archive's ``modelDescription.xml`` in the user's terms, before
    fmpy reads it (its messages: "int() argument must be ... not 'NoneType'" for
    ``fmiVersion="1.0"``, a temporary path that does not exist for a non-UTF-8 file)."""
    try:
        root = ET.fromstring(_description_bytes(path))
    except ET.ParseError as exc:
        return (f"not well-formed XML in its declared encoding ({exc}; an XML file without "
                f"an encoding declaration must be UTF-8)")
    except (OSError, KeyError, zipfile.BadZipFile) as exc:
        return f"cannot be read ({exc})"
    if root.tag != "fmiModelDescription":
        return f"the root element is <{root.tag}>, expected <fmiModelDescription>"
    version = root.get("fmiVersion")
    if version is None:
        return "no fmiVersion attribute (expected fmiVersion=\"2.0\" or \"3.0\")"
    if not version.startswith(("2.", "3.")):
        return (f"fmiVersion {version!r}: uwcosim runs FMI 2.0 and 3.0 FMUs (FMI 1.0 is not "
                f"supported; export the model as FMI 2.0 or 3.0)")
    return None


def binary_problems(path: str | Path, md: ModelDescription,
                    interfaces: tuple[str, ...] = ("cs", "me"),
                    names: list[str] | None = None) -> list[str]:
    """A problem if an interface in ``interfaces`` the FMU declares has no shared library for
    this platform (FMI 2: ``binaries/<fmpy.platform>``, FMI 3: ``binaries/<platform_tuple>``)."""
    import fmpy  # lazy: as in read_model

    path = Path(path)
    plat = fmpy.platform_tuple if md.fmiVersion.startswith("3") else fmpy.platform
    names = member_names(path) if names is None else names
    for iface in interfaces:
        kind = md.coSimulation if iface == "cs" else md.modelExchange
        if kind is None:
            continue
        if not kind.modelIdentifier:  # the binary's name
            tag = "CoSimulation" if iface == "cs" else "ModelExchange"
            return [f"{path}: invalid modelDescription.xml: <{tag}> has no modelIdentifier "
                    f"(the name of its binary, binaries/{plat}/NAME"
                    f"{fmpy.sharedLibraryExtension})"]
        lib = f"binaries/{plat}/{kind.modelIdentifier}{fmpy.sharedLibraryExtension}"
        if lib not in names:
            found = sorted({n.split("/")[1] for n in names
                            if n.startswith("binaries/") and n.count("/") >= 2})
            return [f"{path}: no binary for this platform {plat} ({INTERFACE_NAMES[iface]}: "
                    f"expected {lib}; binaries in the archive: {', '.join(found) or 'none'})"]
    return []


#: the instantiate function each interface needs, by FMI major version
_ENTRY = {("2", "cs"): "fmi2Instantiate", ("2", "me"): "fmi2Instantiate",
          ("3", "cs"): "fmi3InstantiateCoSimulation", ("3", "me"): "fmi3InstantiateModelExchange"}
_LOAD = ("import ctypes, sys\n"
         "lib = ctypes.CDLL(sys.argv[1])\n"
         "missing = [n for n in sys.argv[2:] if not hasattr(lib, n)]\n"
         "print(' '.join(missing))\n")


def library_problems(path: str | Path, md: ModelDescription,
                     interfaces: tuple[str, ...] = ("cs", "me"),
                     timeout_s: float = 30.0) -> list[str]:
    """Problems loading the shared library of each interface in ``interfaces`` (in a child
    process): it cannot be loaded (not a library, a missing dependency, another architecture),
    it crashes when loaded, or it does not export the interface's instantiate function."""
    import fmpy  # lazy: as in read_model

    path = Path(path)
    if binary_problems(path, md, interfaces):
        return []  # reported by binary_problems
    plat = fmpy.platform_tuple if md.fmiVersion.startswith("3") else fmpy.platform
    major = md.fmiVersion[0]
    libs: dict[str, list[str]] = {}
    for iface in interfaces:
        kind = md.coSimulation if iface == "cs" else md.modelExchange
        if kind is None:
            continue
        lib = f"binaries/{plat}/{kind.modelIdentifier}{fmpy.sharedLibraryExtension}"
        libs.setdefault(lib, []).append(_ENTRY[(major, iface)])
    folder = path if path.is_dir() else None
    tmp = None if folder is not None else scratch.make("uwcosim_lib_")
    try:
        out = []
        for lib, symbols in libs.items():
            if folder is not None:
                file = folder / lib
            else:
                with zipfile.ZipFile(path) as zf:
                    zf.extract(lib, tmp)
                file = Path(tmp) / lib
            try:
                r = subprocess.run([sys.executable, "-c", _LOAD, str(file), *symbols],
                                   capture_output=True, text=True, timeout=timeout_s)
            except subprocess.TimeoutExpired:
                out.append(f"{path}: loading {lib} did not finish within {timeout_s:g} s")
                continue
            if r.returncode < 0:
                out.append(f"{path}: loading {lib} crashed the process (signal {-r.returncode})")
            elif r.returncode:
                last = (r.stderr.strip().splitlines() or ["unknown error"])[-1]
                last = last.split(": ", 1)[-1].replace(f"{file}: ", "")
                out.append(f"{path}: {lib} cannot be loaded ({last})")
            elif r.stdout.strip():
                out.append(f"{path}: {lib} does not export {r.stdout.strip()} (not an FMI "
                           f"{md.fmiVersion} binary?)")
        return out
    finally:
        if tmp is not None:
            scratch.remove(tmp)


def open_archive(path: str | Path) -> ModelDescription:
    """Validate the archive (not its binaries) and return its model description; the first
    problem as a one-line :class:`FMUError`."""
    problems = archive_problems(path)
    if problems:
        raise FMUError(problems[0])
    return read_model(path)


def open_description(path: str | Path, interface: str | None = None) -> ModelDescription:
    """Validate the archive (and the binary for ``interface``, or every interface when None)
    and return its model description; the first problem as a one-line :class:`FMUError`."""
    path = Path(path)
    md = open_archive(path)
    ifaces = ("cs", "me") if interface is None else (interface,)
    problems = binary_problems(path, md, ifaces)
    if problems:
        raise FMUError(problems[0])
    return md


def needed_member(name: str) -> bool:
    """True for a member a run of this platform uses: ``modelDescription.xml``, this
    platform's binaries (FMI 2 and FMI 3 names), ``resources/``."""
    import fmpy  # lazy: as in read_model

    return name == "modelDescription.xml" or name.startswith("resources/") or any(
        name.startswith(f"binaries/{p}/") for p in (fmpy.platform, fmpy.platform_tuple))


def unzip(path: str | Path, into: str | Path) -> Path:
    """Extract what a run needs (:func:`needed_member`) of the (checked) archive ``path`` into
    the folder ``into`` unless it already holds it (``modelDescription.xml`` present); a folder
    FMU is used where it is."""
    path, into = Path(path), Path(into)
    if path.is_dir():
        return path
    if (into / "modelDescription.xml").is_file():
        return into
    into.mkdir(parents=True, exist_ok=True)
    try:
        with zipfile.ZipFile(path) as zf:
            zf.extractall(into, [n for n in zf.namelist() if needed_member(n)])
    except (zipfile.BadZipFile, zlib.error, OSError, EOFError) as exc:
        raise FMUError(f"{path}: cannot extract the FMU archive into {into} ({exc})") from None
    return into

"""A user's code named in a scenario: ``package.module:Name`` imported by path, or an entry point.

Two ways to name a user's object (a filter class, a model builder, an FMU spec):

- an **import path** ``package.module:Name`` (``Name`` may be dotted: ``module:Outer.Inner``):
  the module is imported with the scenario's folder and then the current folder put in front
  of ``sys.path`` *for that import only* (:func:`import_object`). ``sys.path`` is restored
  right after: the module stays in ``sys.modules`` (later imports of it, and pickling of its
  objects, find it there), but a module it imports lazily, inside a function, at run time is
  not found through these folders any more; import what you need at the top of the module.
  Module names are global to a Python process: two different files imported under the same
  module name cannot both be used in one process (refused with one line naming both files);
- an **entry point** of an installed distribution (``[project.entry-points."GROUP"]`` in its
  ``pyproject.toml``), named by its entry-point name (:func:`entry_point`,
  :func:`load_entry_point`).

Each resolved object has an :class:`Origin`: how it was found, the module's file and its
sha256, the distribution and version that provide it (if any), and the folder the module was
found in. Runs record it in the log's metadata, so that a run says which code it used.

Every failure is one :class:`~uwcosim.core.errors.ScenarioError` line naming the type string and
the module's error (its exception, file and line), no traceback.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import re
import sys
import traceback
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from uwcosim.core.errors import ScenarioError

_IDENT = r"[A-Za-z_]\w*"
IMPORT_PATH = re.compile(rf"^{_IDENT}(\.{_IDENT})*:{_IDENT}(\.{_IDENT})*$")


def is_import_path(text: object) -> bool:
    """Whether ``text`` is written ``package.module:Name``."""
    return isinstance(text, str) and bool(IMPORT_PATH.match(text))


@dataclass(frozen=True)
class Origin:
    """Where a user's object came from (the ``origin`` of a resolved type string)."""

    #: "built-in", "path" (imported by path), "entry point", "registered" (by a user module)
    source: str
    #: the type string as the scenario gives it
    type: str
    #: ``module:Name`` of the object
    target: str = ""
    module_file: str | None = None
    module_sha256: str | None = None
    #: the installed distribution providing the module, and its version (else the
    #: module's ``__version__``, if it has one)
    package: str | None = None
    version: str | None = None
    #: the folder of ``sys.path`` the module was found in (by path only)
    found_in: str | None = None
    #: the entry-point group (entry points only)
    group: str | None = None

    def record(self) -> dict:
        """The metadata entry of this origin (keys with a value)."""
        return {k: v for k, v in asdict(self).items() if v is not None and v != ""}

    def label(self) -> str:
        """How ``uwcosim list`` names the origin, e.g. ``entry point (gated-ekf 0.1.0)``."""
        if self.source == "built-in":
            return "built-in"
        pkg = f"{self.package} {self.version}" if self.package else (
            f"version {self.version}" if self.version else "")
        where = self.module_file or self.target
        if self.source == "entry point":
            return f"entry point {self.group} ({pkg + ', ' if pkg else ''}{self.target})"
        how = {"path": "by path", "registered": "registered by"}.get(self.source, self.source)
        return f"{how} {where}{' (' + pkg + ')' if pkg else ''}"


def file_sha256(path: str | Path | None) -> str | None:
    """sha256 of a file's bytes (None when there is no readable file)."""
    if not path:
        return None
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def _distribution_of(module_name: str) -> tuple[str | None, str | None]:
    """``(distribution, version)`` of the installed distribution providing ``module_name``'s
    top-level package, else ``(None, its __version__ or None)``."""
    top = module_name.partition(".")[0]
    dists = metadata.packages_distributions().get(top) or []
    for dist in dists:
        try:
            return dist, metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    version = getattr(sys.modules.get(top), "__version__", None)
    return None, str(version) if version is not None else None


def origin_of(obj: Any, type_string: str, source: str, found_in: str | None = None,
              group: str | None = None) -> Origin:
    """The :class:`Origin` of an imported object (its module's file, hash and version)."""
    module_name = getattr(obj, "__module__", None) or ""
    module = sys.modules.get(module_name)
    file = getattr(module, "__file__", None)
    package, version = _distribution_of(module_name) if module_name else (None, None)
    name = getattr(obj, "__qualname__", getattr(obj, "__name__", ""))
    return Origin(source, type_string, f"{module_name}:{name}" if module_name else "",
                  str(Path(file).resolve()) if file else None, file_sha256(file), package,
                  version, found_in, group)


#: the uwcosim package's folder: frames there are not the user's code
_PACKAGE = str(Path(__file__).resolve().parents[1]) + os.sep


def _where_in_user_code(exc: BaseException) -> str:
    """`` (file.py:LINE)`` of the innermost frame of the exception in the user's code (not in
    uwcosim, importlib or Python's frozen modules); empty when there is none."""
    frames = [f for f in traceback.extract_tb(exc.__traceback__)
              if "importlib" not in f.filename and not f.filename.startswith("<frozen")
              and not str(Path(f.filename).resolve()).startswith(_PACKAGE)]
    if isinstance(exc, SyntaxError) and exc.filename:
        return f" ({Path(exc.filename).name}:{exc.lineno})"
    return f" ({Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""


def describe_error(exc: BaseException) -> str:
    """``Type: message (file.py:LINE)`` of an exception raised by a user's code."""
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, SyntaxError):
        msg = exc.msg
    return f"{type(exc).__name__}{': ' + msg if msg else ''}{_where_in_user_code(exc)}"


def _module_file(module_name: str) -> str | None:
    file = getattr(sys.modules.get(module_name), "__file__", None)
    return str(Path(file).resolve()) if file else None


def _shadowed(top: str, dirs: Sequence[Path]) -> str | None:
    """The file or package folder ``top`` would be imported from in ``dirs`` (first match)."""
    for d in dirs:
        for cand in (d / top / "__init__.py", d / f"{top}.py"):
            if cand.is_file():
                return str(cand.resolve())
    return None


def _check_same_module(type_string: str, top: str, dirs: Sequence[Path]) -> None:
    """Refuse a module name already imported from another file than the search folders'."""
    have = _module_file(top)
    want = _shadowed(top, dirs)
    if have is None or want is None or have == want:
        return
    raise ScenarioError(f"type {type_string!r}: module {top!r} is already imported from "
                        f"{have}, not from {want} (module names are global to a process: "
                        f"rename one of them)")


def import_object(type_string: str, search: Sequence[str | Path] = ()) -> tuple[Any, Origin]:
    """Import ``package.module:Name`` with ``search`` folders (e.g. the scenario's folder, then
    the current folder) in front of ``sys.path`` for this import only; ``(object, origin)``.

    ScenarioError (one line) when the string is malformed, the module cannot be imported (its
    error, file and line) or has no such name."""
    if not is_import_path(type_string):
        raise ScenarioError(f"type {type_string!r}: expected 'package.module:Name'")
    module_name, _, attr = type_string.partition(":")
    dirs = [Path(d).resolve() for d in dict.fromkeys(str(d) for d in search)]
    top = module_name.partition(".")[0]
    _check_same_module(type_string, top, dirs)
    added = [str(d) for d in dirs]
    sys.path[:0] = added
    try:
        importlib.invalidate_caches()
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if missing and (module_name == missing or module_name.startswith(missing + ".")):
            looked = ", ".join(added) or "sys.path"
            raise ScenarioError(f"type {type_string!r}: no module named {missing!r} (looked in "
                                f"{looked} and the installed packages)") from None
        raise ScenarioError(f"type {type_string!r}: importing {module_name!r} failed: "
                            f"{describe_error(exc)}") from None
    except Exception as exc:  # noqa: BLE001 - any error of the user's module, in one line
        raise ScenarioError(f"type {type_string!r}: importing {module_name!r} failed: "
                            f"{describe_error(exc)}") from None
    finally:
        for d in added:  # restore sys.path: remove what was added (the first occurrence)
            try:
                sys.path.remove(d)
            except ValueError:
                pass
    obj: Any = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ScenarioError(f"type {type_string!r}: module {module_name!r} "
                                f"({getattr(module, '__file__', '?')}) has no {attr!r}") from None
    file = getattr(module, "__file__", None)
    found = next((d for d in added if file and Path(file).resolve().is_relative_to(d)), None)
    return obj, origin_of(obj, type_string, "path", found)


def entry_points(group: str) -> dict[str, metadata.EntryPoint]:
    """The entry points of ``group`` of the installed distributions, by name (the first
    distribution on ``sys.path`` wins a name)."""
    out: dict[str, metadata.EntryPoint] = {}
    for ep in metadata.entry_points(group=group):
        out.setdefault(ep.name, ep)
    return out


def entry_point(group: str, name: str) -> metadata.EntryPoint | None:
    """The entry point ``name`` of ``group``, or None."""
    return entry_points(group).get(name)


def load_entry_point(group: str, name: str) -> tuple[Any, Origin]:
    """Load the entry point ``name`` of ``group``: ``(object, origin)`` (ScenarioError, one
    line, when there is none or it fails to load)."""
    ep = entry_point(group, name)
    if ep is None:
        raise ScenarioError(f"type {name!r}: no entry point {name!r} in group {group!r}")
    try:
        obj = ep.load()
    except Exception as exc:  # noqa: BLE001 - any error of the user's module, in one line
        raise ScenarioError(f"type {name!r}: loading entry point {ep.value!r} ({group}) "
                            f"failed: {describe_error(exc)}") from None
    origin = origin_of(obj, name, "entry point", group=group)
    dist = getattr(ep, "dist", None)
    if dist is not None:
        origin = Origin(**{**asdict(origin), "package": dist.metadata["Name"],
                           "version": dist.version})
    return obj, origin

"""The Numba binder of the compiled kernels: lazy compilation, the switch, interrupts.

Kernels are plain Python functions decorated with :func:`jit` (or :func:`jit_fast`); Numba is
imported, and every registered kernel bound to its compiled version, at the first call of any
kernel, not at import (about 0.5 s that scenarios without compiled kernels do not pay).
Compiled kernels are cached on disk (``cache=True``), so campaign worker processes load them
instead of compiling. The cache is a folder of its own per version of the kernels'
sources (:func:`kernel_cache_dir`: ``$XDG_CACHE_HOME/uwcosim/numba/<digest>``, unless
``NUMBA_CACHE_DIR`` is set): Numba's index of a kernel follows its own file only, so a
kernel that inlines another module's kernel (``core.bicubic``, ``filters.small_linalg``)
would load stale machine code after that module changed, or fail after it moved. Without
Numba, or with ``UWCOSIM_NUMBA=0``, :data:`ENABLED` is False and the filters run their numpy
forms.

The arithmetic is IEEE in source order (no fast-math): a kernel compiled afresh and the same
kernel loaded from the cache give the same bits (``tests/test_kernel_determinism.py``). The
sums over grids that fast-math used to vectorize are written out in a fixed order instead, in
:mod:`uwcosim.core.reductions`.

A kernel calls another kernel by its module-level name (``from m import kernel``, or
``m.kernel``): the binder replaces the first-call stubs by the compiled kernels in every module
that registers a kernel. Python code calls kernels through their module (``m.kernel(...)``),
so that it reaches the compiled kernel once bound; code that keeps a kernel as a value keeps
:func:`bound` of it (a stub kept would add a Python call to every call).

Argument bundles: kernels take groups of arrays as NamedTuples of named fields (e.g.
:class:`~uwcosim.filters.grid.conditional_kernels.KalmanBlock`), unpack a bundle at their entry
into the names of its fields (``p, k, x, P, F = kal``, free in compiled code) and pass bundles
on to the kernels they call as they received them. A caller may pass the NamedTuple itself or
the plain tuple of its fields (both are typed and unpacked alike); the per-step callers pass
plain tuples: Numba's dispatcher types an exact tuple in C in about 0.05 us, a NamedTuple
(its class and field names fingerprinted on every call) in about 0.5-0.7 us per argument.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import sys
from pathlib import Path

from uwcosim.core.paths import cache_dir

ENABLED = (importlib.util.find_spec("numba") is not None
           and os.environ.get("UWCOSIM_NUMBA", "1") != "0")

#: ``on_compile(name)``, if set: called when Numba starts compiling a kernel because its
#: on-disk cache has no entry for it (after an install or an update: 1-3 min in all, once), not
#: when it loads one (``uwcosim run`` says what it is doing); looked up at each event
on_compile = None

# Every kernel registers here (python function, fastmath flags, first-call stub) until the
# first call of any kernel compiles them all.
_PLAIN: list[tuple] = []


def _compile_all() -> None:
    """Compile every registered kernel (lazily: Numba compiles or loads a kernel from its
    on-disk cache at its first call) and bind the compiled kernels wherever the modules hold
    the first-call stubs (their own names and the names they import from each other)."""
    import numba  # optional dependency: imported at the first kernel call (about 0.5 s)

    listen(_announce)  # once: _PLAIN is empty after this
    compiled = {}
    spaces = {}
    user_dir = numba.config.CACHE_DIR
    # the locator of a kernel's cache is chosen when its dispatcher is made: set only for ours
    numba.config.CACHE_DIR = user_dir or str(kernel_cache_dir(numba.__version__))
    try:
        for fn, fastmath, stub in _PLAIN:
            njit = numba.njit(cache=True, nogil=True, error_model="numpy", fastmath=fastmath)
            compiled[id(stub)] = (stub, njit(fn))
            spaces[id(fn.__globals__)] = fn.__globals__
    finally:
        numba.config.CACHE_DIR = user_dir
    for g in spaces.values():
        for name, value in list(g.items()):
            hit = compiled.get(id(value))
            if hit is not None and hit[0] is value:
                g[name] = hit[1]
    _PLAIN.clear()


def kernel_cache_dir(numba_version: str, package: Path | None = None) -> Path:
    """The on-disk cache of this version of the kernels: a folder named by a SHA-256 over
    Numba's version and the sources of every kernel module (the package's files that import
    :func:`jit`, and any other module whose kernels are being bound), under
    :func:`uwcosim.core.paths.cache_dir`. Any change to a kernel module starts a new cache
    (every kernel compiles once, 1-3 min); older folders can be deleted. ``package``: the
    folder searched for kernel modules (default: uwcosim's)."""
    package = Path(__file__).resolve().parents[1] if package is None else package
    sources = {}
    for path in sorted(package.rglob("*.py")):
        text = path.read_bytes()
        if b"core.jit import" in text:  # a module that makes kernels
            sources[path.relative_to(package).as_posix()] = text
    for fn, _, _ in _PLAIN:  # a user's kernels (``uwcosim.core.jit`` from a plug-in)
        file = Path(sys.modules[fn.__module__].__file__).resolve()
        if not file.is_relative_to(package):
            sources.setdefault(str(file), file.read_bytes())
    digest = hashlib.sha256(numba_version.encode())
    for name, text in sources.items():
        digest.update(f"{name}\0{len(text)}\0".encode())
        digest.update(text)
    return cache_dir() / "numba" / digest.hexdigest()[:16]


def _announce(kernel: str) -> None:
    hook = on_compile
    if hook is not None:
        hook(kernel)


def listen(hook) -> None:
    """Call ``hook(kernel name)`` on Numba's compile events (a cache miss; a load from the
    cache raises none)."""
    from numba.core import event

    class CompileListener(event.Listener):
        def on_start(self, ev) -> None:
            dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            hook(getattr(getattr(dispatcher, "py_func", None), "__qualname__", "kernel"))

        def on_end(self, ev) -> None:
            pass

    event.register("numba:compile", CompileListener())


def _register(fn, fastmath):
    @functools.wraps(fn)
    def first_call(*args):
        if _PLAIN:
            _compile_all()
        return fn.__globals__[fn.__name__](*args)

    _PLAIN.append((fn, fastmath, first_call))
    return first_call


def bound(kernel):
    """The compiled form of the registered ``kernel`` (its first-call stub or itself), binding
    every registered kernel first if none was called yet (imports Numba: call it only when
    :data:`ENABLED`)."""
    if _PLAIN:
        _compile_all()
    fn = getattr(kernel, "__wrapped__", kernel)
    return fn.__globals__[fn.__name__]


def entry_point(kernel, args: tuple):
    """The compiled entry point of the registered ``kernel`` for the Numba types of ``args``,
    loaded from the on-disk cache or compiled as a first call would (imports Numba: call it only
    when :data:`ENABLED`). Calling it skips the dispatcher, which costs a per-step caller of the
    Kalman steps 0.3-2 us per call (:mod:`uwcosim.filters.kalman_kernels`; the larger figure in
    a filter's step loop, ``benchmarks/bench_filters.py --dispatch``). It checks nothing: its
    caller passes arguments of exactly those types on every call, or calls the kernel itself
    when one may differ."""
    from numba.core.typing.typeof import Purpose, typeof

    return bound(kernel).compile(tuple(typeof(a, Purpose.argument) for a in args))


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a KeyboardInterrupt that a compiled kernel wrapped: Ctrl-C landing in
    the Python code Numba runs while it returns arrays surfaces as a ``SystemError`` caused by
    the ``KeyboardInterrupt`` (callers re-raise it as the interrupt it is)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def jit_fast(fn):
    """Kernels that test nothing for finiteness (IEEE arithmetic, as :func:`jit`; kept apart
    so that their flags can be revisited on their own)."""
    return _register(fn, False)


def jit(fn):
    """IEEE arithmetic in source order: no fast-math. Reassociation and contraction let LLVM's
    result depend on what it inlines, and a kernel compiled afresh then differed in the last
    bits from the same kernel loaded from Numba's cache, so that the same scenario and seed
    gave different logs on a fresh machine (measured: 1e-11 m in PFM-PSI's estimate). What
    fast-math bought (vectorized sums) is written out instead: sums over grids keep several
    partial sums combined in a fixed order (:func:`uwcosim.core.reductions.row_sum`), legal to
    vectorize as IEEE."""
    return _register(fn, False)

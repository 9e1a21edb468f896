"""The one FMU archive validator (uwcosim.fmi.archive) used by the master and `fmu info`.

Broken archives are made from the project's DVL FMU: a member with corrupt deflate data, an
absolute or ``..`` member name, no binary for this platform, a shared library that does not
load. Each is refused with the same one-line FMUError by the adapter and by ``fmu info`` (and
listed by ``validate``); loading a broken library leaves the working directory alone.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import zipfile

import pytest

from uwcosim.core.errors import FMUError
from uwcosim.fmi.adapter import FMUAdapter
from uwcosim.fmi.archive import archive_problems, open_description
from uwcosim.fmu.info import fmu_info, validate

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]


def _rewrite(src, dst, rename=None, replace=None):
    """Copy the archive ``src`` to ``dst`` renaming members / replacing their data."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item)
            name = item.filename
            if replace and name in replace:
                data = replace[name]
            if rename:
                name = rename(name)
            zout.writestr(name, data)
    return dst


def _corrupt_deflate(src, dst, member="modelDescription.xml"):
    """``src`` with the deflate stream of ``member`` overwritten (CRC and sizes unchanged)."""
    _rewrite(src, dst)
    with zipfile.ZipFile(dst) as zf:
        info = zf.getinfo(member)
    data = bytearray(dst.read_bytes())
    # local header: 30 bytes + name + extra field, then the compressed data
    n_name = int.from_bytes(data[info.header_offset + 26: info.header_offset + 28], "little")
    n_extra = int.from_bytes(data[info.header_offset + 28: info.header_offset + 30], "little")
    start = info.header_offset + 30 + n_name + n_extra
    data[start: start + min(64, info.compress_size)] = b"\xff" * min(64, info.compress_size)
    dst.write_bytes(bytes(data))
    return dst


@pytest.fixture
def dvl(project_fmus):
    return project_fmus / "DVL.fmu"


def _all_refuse(path, expected, info=True):
    """The adapter, open_description and fmu info refuse ``path`` with ``expected`` (``fmu
    info`` describes an FMU without a binary for this platform: it lists the platforms)."""
    calls = [lambda: FMUAdapter("dvl", path), lambda: open_description(path)]
    for call in calls + ([lambda: fmu_info(path)] if info else []):
        with pytest.raises(FMUError, match=re.escape(expected)) as info:
            call()
        assert str(path) in str(info.value) and "\n" not in str(info.value)
    problems = validate(path)
    assert problems and expected in problems[0]


def test_corrupt_deflate_member(dvl, tmp_path):
    bad = _corrupt_deflate(dvl, tmp_path / "deflate.fmu")
    _all_refuse(bad, "corrupt FMU archive (member 'modelDescription.xml': ")


def test_bad_crc(dvl, tmp_path):
    bad = tmp_path / "crc.fmu"
    with zipfile.ZipFile(dvl) as zin, zipfile.ZipFile(bad, "w", zipfile.ZIP_STORED) as zout:
        for item in zin.infolist():
            zout.writestr(item.filename, zin.read(item))
    with zipfile.ZipFile(bad) as zf:
        info = zf.getinfo("modelDescription.xml")
    data = bytearray(bad.read_bytes())
    n_name = int.from_bytes(data[info.header_offset + 26: info.header_offset + 28], "little")
    n_extra = int.from_bytes(data[info.header_offset + 28: info.header_offset + 30], "little")
    data[info.header_offset + 30 + n_name + n_extra + 100] ^= 0x01  # one bit of the XML
    bad.write_bytes(bytes(data))
    _all_refuse(bad, "corrupt FMU archive (member 'modelDescription.xml': Bad CRC-32")


@pytest.mark.parametrize("name", ["/etc/evil", "../evil.txt", "resources/../../evil.txt"])
def test_unsafe_member_names(dvl, tmp_path, name):
    bad = tmp_path / "unsafe.fmu"
    with zipfile.ZipFile(dvl) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, zin.read(item))
        zout.writestr(name, b"x")
    _all_refuse(bad, "unsafe FMU archive")
    assert repr(name) in archive_problems(bad)[0]


def test_good_archive_has_no_problems(dvl):
    assert archive_problems(dvl) == []
    assert open_description(dvl, "cs").modelName


def test_missing_binary_for_this_platform(dvl, tmp_path):
    bad = _rewrite(dvl, tmp_path / "foreign.fmu", rename=lambda n: n.replace(
        "x86_64-linux", "aarch64-darwin").replace(".so", ".dylib"))
    _all_refuse(bad, "no binary for this platform", info=False)
    assert "this platform     no binary for this platform" in fmu_info(bad)
    assert "this platform     binary ok" in fmu_info(dvl)


def _broken_library(dvl, tmp_path):
    with zipfile.ZipFile(dvl) as zf:
        lib = [n for n in zf.namelist() if n.startswith("binaries/") and n.endswith(".so")]
    return _rewrite(dvl, tmp_path / "broken.fmu", replace={n: b"not a library" for n in lib})


def test_library_that_does_not_load_keeps_the_working_directory(dvl, tmp_path):
    bad = _broken_library(dvl, tmp_path)
    ad = FMUAdapter("dvl", bad)  # the archive itself is fine
    cwd = os.getcwd()
    with pytest.raises(FMUError, match="cannot instantiate FMU 'dvl'.*shared library"):
        ad.instantiate({}, {}, 0.0, 1.0)
    assert os.getcwd() == cwd
    ad.close()


def test_cli_relative_out_with_a_library_that_does_not_load(dvl, tmp_path):
    bad = _broken_library(dvl, tmp_path)
    r = subprocess.run(
        [sys.executable, "-m", "uwcosim", "run", str(ROOT / "scenarios" / "tan_terrain.toml"),
         "--set", f'fmus.dvl.path="{bad}"', "--set", "run.duration=5", "--out", "rel/run"],
        capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert r.returncode == 3, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0
    assert "cannot instantiate FMU 'dvl'" in r.stderr and "shared library" in r.stderr


def test_an_unzipped_fmu_folder_is_used_where_it_is(dvl, tmp_path):
    folder = tmp_path / "DVL"
    with zipfile.ZipFile(dvl) as zf:
        zf.extractall(folder)
    ad = FMUAdapter("dvl", folder)
    out = ad.bind(["vx_m"])
    try:
        ad.instantiate({}, {}, 0.0, 1.0)
        ad.do_step(0.0, 1.0, ad.bind([]), None)
        assert ad.get_outputs(out, 1.0).shape == (1,)
    finally:
        ad.close()
    assert (folder / "modelDescription.xml").is_file()  # not deleted by close()

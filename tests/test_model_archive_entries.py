"""Archive safety (cosim.model.archive) for entries with '..' anywhere in their path, not only as its first part:
refused before anything is written, by the library (check_archive, safe_extract, check_entries) and by
``wmr-cosim check`` (exit 2, one line naming the archive and the entry).  The rule is any '..' component:
one that climbs out of the folder ('resources/a/../../../x') is named as such, one that stays inside it
('resources/a/..', 'resources/a/../../x') is refused all the same."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest

from cosim_support import edited_fmu, write_scenario
from reference_fmus import REF
from wmr_cosim import cli
from wmr_cosim.cosim.model.archive import check_archive, check_entries, escapes, safe_extract
from wmr_cosim.cosim.messages.errors import FmuLoadError

OUTSIDE = "would extract outside its folder"
INSIDE = "has a '..' component (refused even where it stays inside the folder)"
ENTRIES = [
    ("resources/a/../../../x.txt", OUTSIDE),      # climbs out in its middle
    ("resources/a/b/c/../../../../../x.txt", OUTSIDE),   # climbs out at its last '..'
    ("resources\\a\\..\\..\\..\\x.txt", OUTSIDE),  # the same with backslashes
    ("resources/a/../../x.txt", INSIDE),          # back to the top, not above it
    ("resources/a/..", INSIDE),                   # stays inside
    ("resources/a/../b.txt", INSIDE),
]


def _with_entry(dst: Path, entry: str) -> Path:
    """The Reference FMU Feedthrough (FMI 2.0) with one more entry, ``entry``, holding a few bytes."""
    with zipfile.ZipFile(REF / "fmi2" / "Feedthrough.fmu") as zi, zipfile.ZipFile(dst, "w") as zo:
        for info in zi.infolist():
            zo.writestr(info, zi.read(info))
        zo.writestr(zipfile.ZipInfo(entry), b"escaped")
    return dst


def _tree(root: Path) -> list[Path]:
    return sorted(root.rglob("*"))


@pytest.mark.parametrize("entry, why", ENTRIES)
def test_an_entry_with_dotdot_anywhere_is_refused_before_anything_is_written(tmp_path, entry, why):
    box = tmp_path / "a" / "b" / "c" / "box"      # deep enough that nothing escaping could leave tmp_path
    box.mkdir(parents=True)
    fmu = _with_entry(box / "Feedthrough.fmu", entry)
    assert zipfile.ZipFile(fmu).namelist()[-1] == entry
    message = f"{fmu}: refused: entry '{entry}' {why}"
    before = _tree(tmp_path)
    with pytest.raises(FmuLoadError) as exc:
        check_archive(fmu)
    assert str(exc.value) == message
    (box / "existing").mkdir()
    before = _tree(tmp_path)
    for dest in (box / "new" / "folder", box / "existing"):
        with pytest.raises(FmuLoadError) as exc:
            safe_extract(fmu, dest)
        assert str(exc.value) == message
        assert _tree(tmp_path) == before           # nothing extracted, no folder made
    with pytest.raises(FmuLoadError) as exc:
        check_entries("label", [zipfile.ZipInfo("modelDescription.xml"), zipfile.ZipInfo(entry)])
    assert str(exc.value) == f"label: refused: entry '{entry}' {why}"


def test_entries_without_dotdot_pass():
    check_entries("label", [zipfile.ZipInfo(n) for n in ("modelDescription.xml", "resources/a..b/c..",
                                                          "resources/..a/b", "resources/./x", "sources/")])


@pytest.mark.parametrize("path, out", [("../x", True), ("a/../../x", True), ("a/b/../../../x", True),
                                       ("a/..", False), ("a/../b", False), ("a/b/../../c", False),
                                       ("a/../b/../..", True), ("a/b/c", False)])
def test_escapes_follows_the_normalised_path(path, out):
    from pathlib import PurePosixPath

    assert escapes(PurePosixPath(path).parts) is out


@pytest.mark.parametrize("entry, why", [ENTRIES[0], ENTRIES[4]])
def test_check_refuses_it_in_one_line_with_exit_2(tmp_path, capsys, entry, why):
    """``wmr-cosim check`` of a scenario with such an FMU, and of the FMU alone: exit 2, one line naming the
    archive and the entry, nothing written."""
    fmu = _with_entry(tmp_path / "Feedthrough.fmu", entry)
    scen = write_scenario(tmp_path / "s.toml", f'[experiment]\nstop = 0.1\nstep = 0.01\n'
                                               f'[instances.ft]\nfmu = "{fmu}"\n')
    before = _tree(tmp_path)
    for target in (scen, fmu):
        code = cli.main(["check", str(target)])
        out, err = capsys.readouterr()
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, err
        assert f"{fmu}: refused: entry '{entry}' {why}" in lines[0], lines[0]
        assert _tree(tmp_path) == before


def _corrupt_deflate(src: Path, out: Path, entry: str) -> Path:
    """``src`` with the compressed data of ``entry`` overwritten by bytes no inflater accepts (0xff: an
    invalid block type), its directory and sizes intact."""
    data = bytearray(edited_fmu(src, out, lambda name, data: data).read_bytes())
    with zipfile.ZipFile(out) as zf:
        info = zf.getinfo(entry)
    name_len, extra_len = int.from_bytes(data[info.header_offset + 26:info.header_offset + 28], "little"), \
        int.from_bytes(data[info.header_offset + 28:info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_len + extra_len
    data[start:start + min(16, info.compress_size)] = b"\xff" * min(16, info.compress_size)
    out.write_bytes(bytes(data))
    return out


@pytest.mark.parametrize("entry", ["modelDescription.xml", "binaries/linux64/Dahlquist.so"])
def test_an_entry_whose_compressed_data_is_corrupt_is_refused_in_one_line(tmp_path, capsys, entry):
    bad = _corrupt_deflate(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "bad.fmu", entry)
    with pytest.raises(FmuLoadError, match=f"entry '{entry}' cannot be read"):
        check_archive(bad)
    for cmd in ("info", "check"):
        assert cli.main([cmd, str(bad)]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "bad.fmu" in lines[0] and "cannot be read" in lines[0], lines


def test_a_model_description_in_an_unknown_encoding_is_refused_in_one_line(tmp_path, capsys):
    def edit(name: str, data: bytes) -> bytes:
        if name == "modelDescription.xml":
            data = data.replace(b'encoding="UTF-8"', b'encoding="no-such-encoding"', 1)
            assert b"no-such-encoding" in data
        return data
    bad = edited_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "enc.fmu", edit)
    for cmd in ("info", "check"):
        assert cli.main([cmd, str(bad)]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "enc.fmu" in lines[0] and "no-such-encoding" in lines[0], lines


@pytest.mark.parametrize("attribute, value", [("startTime", ""), ("stopTime", "soon"), ("stepSize", "nan"),
                                              ("tolerance", "1e999")])
def test_a_default_experiment_that_is_not_a_finite_number_is_refused_in_one_line(tmp_path, capsys, attribute, value):
    def edit(name: str, data: bytes) -> bytes:
        if name == "modelDescription.xml":
            text = data.decode("utf-8")
            text = re.sub(r"<DefaultExperiment[^>]*/>", f'<DefaultExperiment {attribute}="{value}"/>', text)
            assert f'{attribute}="{value}"' in text
            data = text.encode("utf-8")
        return data
    bad = edited_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "de.fmu", edit)
    for argv in (["check", str(bad)], ["run", str(bad), "--out", str(tmp_path / "out"), "--quiet"]):
        assert cli.main(argv) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "de.fmu" in lines[0] and f"DefaultExperiment {attribute}" in lines[0], lines
    assert not (tmp_path / "out").exists()
    assert cli.main(["info", str(bad)]) == 0   # info describes it as it is
    assert "default experiment:" in capsys.readouterr().out


# ---------------------------------------------------------------------- what a run unpacks
def test_a_run_unpacks_the_model_description_resources_and_this_platforms_binaries_only(tmp_path):
    """Sources, documentation, extra/ and other platforms' binaries stay packed (an FMU may assume nothing
    outside its resources); the archive is still checked whole: an unsafe entry among the ones left out
    refuses it all the same."""
    from wmr_cosim.cosim.model.archive import run_members

    src = edited_fmu(REF / "fmi2" / "Feedthrough.fmu", tmp_path / "f.fmu", lambda n, b: b)
    with zipfile.ZipFile(src, "a") as zf:
        zf.writestr("resources/data/table.txt", "1 2 3\n")
        zf.writestr("binaries/win64/Feedthrough.dll", b"MZ")
        zf.writestr("documentation/index.html", "<p>doc</p>")
    out = safe_extract(src, tmp_path / "x", only=run_members("linux64"))
    got = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert got == ["binaries/linux64/Feedthrough.so", "modelDescription.xml", "resources/data/table.txt"]
    assert (out / "resources" / "data" / "table.txt").read_text() == "1 2 3\n"
    bad = edited_fmu(src, tmp_path / "bad.fmu", lambda n, b: b)
    with zipfile.ZipFile(bad, "a") as zf:
        zf.writestr("sources/../../evil.c", "x")
    with pytest.raises(FmuLoadError, match="evil.c"):
        safe_extract(bad, tmp_path / "y", only=run_members("linux64"))
    assert not (tmp_path / "y").exists()


def test_a_model_is_read_once_while_its_file_stays_the_same(tmp_path):
    """load_model reads an FMU once per process (the plan and an SSP's loading both ask for it); the file
    changed (rewritten in place, or replaced) is read again, and a model asked for by another path names
    that path."""
    import os
    import shutil

    from wmr_cosim.cosim.model.description import load_model

    path = shutil.copy(REF / "fmi2" / "Feedthrough.fmu", tmp_path / "f.fmu")
    first = load_model(path)
    assert load_model(path) is first
    edited_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "d.fmu", lambda n, b: b)
    os.replace(tmp_path / "d.fmu", path)                      # replaced: another inode
    assert load_model(path).md.modelName == "Dahlquist"
    with open(path, "r+b") as fh:                             # rewritten in place: other times
        fh.write(Path(REF / "fmi2" / "Feedthrough.fmu").read_bytes())
        fh.truncate()
    assert load_model(path).md.modelName == "Feedthrough"
    os.symlink(path, tmp_path / "link.fmu")
    assert load_model(tmp_path / "link.fmu").path == tmp_path / "link.fmu"

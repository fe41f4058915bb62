"""An FMU whose binary cannot be loaded is refused at ``check``, one line naming the instance, the file and
the reason, for co-simulation and model exchange, FMI 2.0 and 3.0 (cosim/model/binary.py reads the library's
header and exports); a binary that passes that reading and still fails to load (a library it links
against is missing) ends ``run`` in one line naming the instance and the loader's reason."""
from __future__ import annotations

import ctypes.util
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from elf_files import elf_file
from reference_fmus import DATA, PLATFORM, REF
from wmr_cosim.cli import main
from wmr_cosim.cosim.model.binary import REQUIRED, library_problem
from wmr_cosim.cosim.model.description import load_model


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def _with_binary(src: Path, out: Path, binary: bytes | None = None, patch: dict[int, bytes] | None = None) -> Path:
    """A copy of the FMU ``src`` whose binaries are ``binary``, or are patched at the given offsets."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename.startswith("binaries/") and not info.filename.endswith("/"):
                if binary is not None:
                    data = binary
                for at, new in (patch or {}).items():
                    data = data[:at] + new + data[at + len(new):]
            zout.writestr(info, data)
    return out


def _scenario(folder: Path, fmu: Path, interface: str) -> Path:
    path = folder / "bad.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.bad]\nfmu = "{fmu}"\n'
                    f'interface = "{interface}"\n')
    return path


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("interface", ["co-simulation", "model-exchange"])
def test_a_text_file_as_binary_is_refused_at_check_naming_the_instance(tmp_path, capsys, version, interface):
    bad = _with_binary(REF / version / "BouncingBall.fmu", tmp_path / "BouncingBall.fmu", b"not a library\n")
    rc = main(["check", str(_scenario(tmp_path, bad, interface))])
    err = _one_line(capsys)
    assert rc == 2
    assert "instances.bad" in err and f"binaries/{PLATFORM[version]}/BouncingBall.so" in err, err
    assert "not an ELF shared library" in err, err


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_a_bad_binary_given_alone_is_refused_at_check(tmp_path, capsys, version):
    bad = _with_binary(REF / version / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", b"#!/bin/sh\n")
    assert main(["check", str(bad)]) == 2
    assert "Dahlquist.so cannot be loaded" in _one_line(capsys)
    assert main(["check", str(bad), "--solver", "cvode"]) == 2
    assert "Dahlquist.so cannot be loaded" in _one_line(capsys)


def test_an_elf_for_another_machine_is_refused(tmp_path, capsys):
    arm = _with_binary(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", patch={18: b"\xb7\x00"})
    assert main(["check", str(arm)]) == 2
    assert "an ELF file for AArch64, not x86-64" in _one_line(capsys)


def test_a_library_that_does_not_export_the_fmi_functions_is_refused():
    libm = ctypes.util.find_library("m")
    path = next(p for p in (Path("/lib/x86_64-linux-gnu") / str(libm), Path("/usr/lib/x86_64-linux-gnu") / str(libm))
                if p.is_file())
    why = library_problem(path.read_bytes(), 2, "co-simulation", "linux")
    assert why == "exports no fmi2Instantiate, fmi2DoStep"
    data = path.read_bytes()
    assert library_problem(data[:len(data) // 4], 2, "co-simulation", "linux") is not None   # truncated


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_working_binaries_pass_for_each_interface_they_declare(version):
    for model in ("BouncingBall", "Dahlquist", "Feedthrough", "VanDerPol"):
        m = load_model(REF / version / f"{model}.fmu")
        assert m.missing_binaries == {}, (model, m.missing_binaries)
        assert set(m.interfaces) == {"co-simulation", "model-exchange"}


def test_our_fmus_binaries_export_what_their_interface_needs(built_fmus):
    for fmu in built_fmus.values():
        m = load_model(fmu)
        assert m.missing_binaries == {} and m.interfaces == ("co-simulation",)
        with zipfile.ZipFile(fmu) as zf:
            data = zf.read(f"binaries/linux64/{m.identifier}.so")
        assert library_problem(data, 2, "co-simulation", "linux") is None
        assert library_problem(data, 2, "model-exchange", "linux") == "exports no fmi2GetDerivatives"


def test_the_required_functions_are_the_ones_fmpy_calls_for_each_interface():
    import fmpy.fmi2
    import fmpy.fmi3
    for (fmi, interface), names in REQUIRED.items():
        module = fmpy.fmi2 if fmi == 2 else fmpy.fmi3
        source = Path(module.__file__).read_text(encoding="utf-8")
        for name in names:
            assert f"'{name}'" in source or f'"{name}"' in source or f"{name}(" in source, (fmi, interface, name)


def _ghost_dahlquist(tmp_path: Path) -> Path:
    """Dahlquist (FMI 2.0) compiled against a library that is then removed: its header and exports are
    right, and the loader refuses it for the missing dependency."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("needs a C compiler")
    import fmpy
    ghost = tmp_path / "libghost.so"
    (tmp_path / "ghost.c").write_text("int ghost(void) { return 1; }\n")
    subprocess.run([cc, "-shared", "-fPIC", str(tmp_path / "ghost.c"), "-o", str(ghost)], check=True)
    own, common = DATA / "models" / "Dahlquist", DATA / "common"
    so = tmp_path / "Dahlquist.so"
    subprocess.run([cc, "-shared", "-fPIC", "-O1", "-DFMI_VERSION=2", "-DDISABLE_PREFIX",
                    f"-I{Path(fmpy.__file__).parent / 'c-code'}", f"-I{own}", f"-I{common}", str(own / "model.c"),
                    str(common / "cosimulation.c"), str(common / "fmi2Functions.c"), "-o", str(so),
                    "-Wl,--no-as-needed", f"-L{tmp_path}", "-lghost", "-lm"], check=True)
    ghost.unlink()
    fmu = _with_binary(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", so.read_bytes())
    so.unlink()
    return fmu


@pytest.mark.parametrize("how", [[], ["--solver", "cvode"], ["--isolate"]])
def test_a_binary_the_loader_refuses_ends_the_run_in_one_line(tmp_path, capsys, monkeypatch, how):
    fmu = _ghost_dahlquist(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["check", str(fmu), *(a for a in how if a != "--isolate")]) == 0, capsys.readouterr().err
    capsys.readouterr()
    rc = main(["run", str(fmu), *how, "--out", "out", "--quiet"])
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    first = err.splitlines()[0]
    assert rc == 1 and "Dahlquist" in first and "binaries/linux64/Dahlquist.so" in first, err
    assert "libghost.so: cannot open shared object file" in first, err
    assert (tmp_path / "out" / "summary.json").is_file()


# --- the reader's work on a stranger's binary: linear in its size, whatever its tables say -------------------

def test_the_export_reader_reads_names_where_the_string_table_shares_them():
    """A linker shares the tail of a string ("my_fmi2DoStep" holds "fmi2DoStep"); only symbols defined
    here (section index not 0) count."""
    strtab = b"\0my_fmi2DoStep\0fmi2Instantiate\0"
    defined = elf_file(strtab, [(0, 0), (4, 5), (15, 5)])
    assert library_problem(defined, 2, "co-simulation", "linux") is None
    assert library_problem(elf_file(strtab, [(0, 0), (1, 5), (15, 5)]), 2, "co-simulation", "linux") == \
        "exports no fmi2DoStep"   # my_fmi2DoStep is another name
    assert library_problem(elf_file(strtab, [(0, 0), (4, 0), (15, 5)]), 2, "co-simulation", "linux") == \
        "exports no fmi2DoStep"   # undefined: imported from elsewhere


def test_100k_symbols_over_an_unterminated_string_table_are_read_in_linear_time():
    """100,000 symbols whose names all begin in the first 1 MB of a string table that has no terminator
    before the FMI functions' names at its end.  The reader that read each symbol's name scanned the table
    up to that first terminator for each (5 * 10^10 bytes scanned and copied: minutes); the reader looks up
    each symbol's name offset among the places the wanted names begin (found by one search of the table
    each), so its work is one pass over the table and one over the symbols: hundredths of a second here.
    The bound of 10 s is generous against a loaded machine and far below the quadratic reader's minutes;
    the speed itself is measured by ``benchmarks/bench.py binary``."""
    import time
    n, long = 100_000, 1_000_000
    strtab = b"x" * long + b"\0fmi2Instantiate\0fmi2DoStep\0"
    data = elf_file(strtab, [(i * 10, 5) for i in range(n)] + [(long + 1, 5), (long + 17, 5)])
    t0 = time.perf_counter()
    why = library_problem(data, 2, "co-simulation", "linux")
    assert time.perf_counter() - t0 < 10.0
    assert why is None
    assert library_problem(elf_file(strtab, [(i * 10, 5) for i in range(n)] + [(long + 1, 5)]), 2,
                           "co-simulation", "linux") == "exports no fmi2DoStep"


def test_hostile_section_and_symbol_tables_are_refused_without_reading_them():
    strtab = b"\0fmi2Instantiate\0fmi2DoStep\0"
    many = elf_file(strtab, [(0, 0)] * 100_000 + [(1, 5), (17, 5)], dynsym_sections=60_000)
    assert library_problem(many, 2, "co-simulation", "linux") == \
        "a truncated or malformed ELF file (60000 dynamic symbol tables)"
    outside = elf_file(strtab, [(1, 5), (17, 5)], sym_off=1 << 62)
    assert library_problem(outside, 2, "co-simulation", "linux") == \
        "a truncated or malformed ELF file (its dynamic symbol table lies outside it)"


def test_mutated_binaries_get_an_answer_never_an_exception():
    """A bounded fuzz of both readers: real headers with bytes changed at random (seeded) give None or a
    phrase, never an exception."""
    import random
    import struct
    rng = random.Random(55)
    with zipfile.ZipFile(REF / "fmi2" / "Dahlquist.fmu") as zf:
        elf = zf.read("binaries/linux64/Dahlquist.so")
    pe = bytearray(1024)
    pe[:2], pe[0x3C:0x40] = b"MZ", struct.pack("<I", 0x80)
    pe[0x80:0x84] = b"PE\0\0"
    pe[0x84:0x98] = struct.pack("<HHIIIHH", 0x8664, 1, 0, 0, 0, 0xF0, 0x2022)
    assert library_problem(bytes(pe), 2, "co-simulation", "win32") is None
    for data, platform, span in ((elf, "linux", 64 + 56 * 4), (bytes(pe), "win32", 0x98)):
        for _ in range(1500):
            mutated = bytearray(data[:rng.choice((len(data), rng.randrange(1, len(data))))])
            for _ in range(rng.randrange(1, 6)):
                if mutated:
                    mutated[rng.randrange(min(span, len(mutated)))] = rng.randrange(256)
            why = library_problem(bytes(mutated), 2, "co-simulation", platform)
            assert why is None or isinstance(why, str)
    # the program and section header tables' offsets, entry sizes and counts, each set to extremes
    for at, width in ((32, 8), (40, 8), (54, 2), (56, 2), (58, 2), (60, 2)):
        for value in (0, 1, (1 << (8 * width)) - 1):
            bad = elf[:at] + value.to_bytes(width, "little") + elf[at + width:]
            why = library_problem(bad, 2, "co-simulation", "linux")
            assert why is None or why.startswith(("a truncated or malformed ELF file", "exports no")), (at, why)


@pytest.mark.parametrize("how, why", [(["-no-pie"], "an executable, not a shared object"),
                                      (["-pie"], "a position-independent executable (DF_1_PIE), not a shared object")])
def test_an_executable_is_refused_at_check_though_it_exports_the_fmi_functions(tmp_path, capsys, how, why):
    """A program (an executable, or a position-independent one: an ELF shared object by its type, whose
    DT_FLAGS_1 has DF_1_PIE) that exports the FMI functions (-rdynamic) is no library: the loader refuses
    to dlopen it ("cannot dynamically load ... executable"), so ``check`` refuses it, naming the FMU and the
    binary."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("needs a C compiler")
    src = tmp_path / "program.c"
    src.write_text("int fmi2Instantiate(void) { return 0; }\nint fmi2DoStep(void) { return 0; }\n"
                   "int fmi2GetDerivatives(void) { return 0; }\nint main(void) { return fmi2DoStep(); }\n")
    exe = tmp_path / "program"
    subprocess.run([cc, *how, "-rdynamic", "-fPIE" if how == ["-pie"] else "-fno-pie", str(src), "-o", str(exe)],
                   check=True)
    ctypes_refusal = None
    try:
        ctypes.CDLL(str(exe))
    except OSError as exc:
        ctypes_refusal = str(exc)
    assert ctypes_refusal is not None and "executable" in ctypes_refusal   # what the loader says of it
    fmu = _with_binary(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", exe.read_bytes())
    for path in (src, exe):
        path.unlink()
    assert main(["check", str(fmu)]) == 2
    assert _one_line(capsys).endswith(f"{fmu}: binaries/linux64/Dahlquist.so cannot be loaded: {why}")
    rc = main(["check", str(_scenario(tmp_path, fmu, "model-exchange"))])
    err = _one_line(capsys)
    assert rc == 2 and "instances.bad" in err and "Dahlquist.so" in err and why in err, err

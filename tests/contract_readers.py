"""The readers of untrusted bytes and their fuzz (not a test module): FMU archives (zip), model descriptions
(modelDescription.xml of FMI 2.0 and 3.0), ELF and PE binaries (cosim/model/binary.py), and a results
folder's files (signals.npy, requirements.npy, summary.json, scenario.json: what ``plot`` reads).
(signals.mat is written by the project and read by other tools only: there is no reader of ours to fuzz.)

Each reader has valid seeds; :func:`mutations` turns a seed into hostile bytes (bits flipped, the bytes cut
short, a part spliced in elsewhere, a field overwritten with a huge count, a region zeroed, random bytes
inserted), :func:`xml_mutations` does the same to the XML's structure (attributes emptied, made huge, not
finite or negative; elements dropped or duplicated; entity expansion; deep nesting; not UTF-8).  A reader
answers with a value or a clean error (the project's CosimError family, one line through the command line),
never another exception, within a time limit and bounded memory.
"""
from __future__ import annotations

import io
import re
import zipfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, Callable

from hypothesis import strategies as st

from contract_strategies import Case


# --- byte mutations -------------------------------------------------------------------------------------
@st.composite
def mutations(draw: Any, seed: bytes, header: int = 256) -> tuple[bytes, str]:
    """``seed`` with one to three mutations (most of them in its first ``header`` bytes, where the counts
    and offsets are), and their names."""
    data = bytearray(seed)
    names = []
    for _ in range(draw(st.integers(1, 3))):
        how = draw(st.sampled_from(["bitflip", "truncate", "splice", "huge_count", "zero", "insert"]))
        names.append(how)
        n = len(data)
        if n == 0:
            data += draw(st.binary(min_size=1, max_size=64))
            continue
        near = draw(st.booleans())
        pos = draw(st.integers(0, min(n, header) - 1 if near else n - 1))
        if how == "bitflip":
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif how == "truncate":
            del data[draw(st.integers(0, n - 1)):]
        elif how == "splice":
            a = draw(st.integers(0, n - 1))
            chunk = bytes(data[a:a + draw(st.integers(1, 512))])
            data[pos:pos] = chunk
        elif how == "huge_count":
            width = draw(st.sampled_from([2, 4, 8]))
            value = draw(st.sampled_from([0xFF, 0x7F, 0x80])) * (1 << (8 * width - 8)) + (1 << (8 * width - 8)) - 1
            data[pos:pos + width] = value.to_bytes(width, "little")
        elif how == "zero":
            end = min(n, pos + draw(st.integers(1, 4096)))
            data[pos:end] = bytes(end - pos)
        else:
            data[pos:pos] = draw(st.binary(min_size=1, max_size=64))
    return bytes(data), "+".join(names)


# --- seeds ----------------------------------------------------------------------------------------------
@cache
def fmu_seed(version: str = "fmi2", model: str = "Dahlquist") -> bytes:
    from reference_fmus import fmu

    return fmu(version, model).read_bytes()


def members(archive: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(archive)) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}


def rezip(files: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buf.getvalue()


@cache
def elf_seed() -> bytes:
    return next(v for k, v in members(fmu_seed()).items() if k.endswith(".so"))


@cache
def pe_seed() -> bytes:
    """A real x64 DLL: the one FMPy ships for its logging on Windows (else a minimal PE header)."""
    import fmpy

    dll = Path(fmpy.__file__).parent / "logging" / "win64" / "logging.dll"
    if dll.is_file():
        return dll.read_bytes()
    pe = bytearray(512)
    pe[:2], pe[0x3C:0x40] = b"MZ", (0x80).to_bytes(4, "little")
    pe[0x80:0x84], pe[0x84:0x86], pe[0x96:0x98] = b"PE\0\0", (0x8664).to_bytes(2, "little"), (0x2022).to_bytes(2, "little")
    return bytes(pe)


# --- XML mutations --------------------------------------------------------------------------------------
_ATTR = re.compile(rb'(\w+)="([^"]*)"')


@st.composite
def xml_mutations(draw: Any, xml: bytes) -> tuple[bytes, str]:
    """The model description with one structural mutation, and its name."""
    how = draw(st.sampled_from(["attribute", "attribute", "drop_line", "duplicate_line", "entities", "deep",
                                "not_utf8", "encoding", "truncate", "version", "bytes"]))
    lines = xml.split(b"\n")
    if how == "attribute":
        attrs = list(_ATTR.finditer(xml))
        m = draw(st.sampled_from(attrs))
        value = draw(st.sampled_from([b"", b"nan", b"inf", b"-inf", b"1e999", b"-1", b"-2147483649",
                                      b"99999999999999999999", b"x" * 100_000, b"&#0;", b"\xc3\x28", b"0x10",
                                      b"1 2", b"true", b"{}"]))
        return xml[:m.start(2)] + value + xml[m.end(2):], f"{m.group(1).decode()}={value[:20]!r}"
    if how == "drop_line" and len(lines) > 2:
        i = draw(st.integers(1, len(lines) - 1))
        return b"\n".join(lines[:i] + lines[i + 1:]), f"line {i} dropped"
    if how == "duplicate_line" and len(lines) > 2:
        i = draw(st.integers(1, len(lines) - 1))
        return b"\n".join(lines[:i] + [lines[i]] * draw(st.integers(2, 2000)) + lines[i + 1:]), f"line {i} repeated"
    if how == "entities":
        bomb = (b'<?xml version="1.0"?>\n<!DOCTYPE fmiModelDescription [<!ENTITY a "aaaaaaaaaa">'
                + b"".join(b'<!ENTITY %s "%s">' % (bytes([98 + i]), (b"&" + bytes([97 + i]) + b";") * 10)
                           for i in range(8)) + b"]>\n")
        body = xml.split(b"?>", 1)[-1].replace(b'description="', b'description="&i;', 1)
        return bomb + body, "entity expansion"
    if how == "deep":
        n = draw(st.integers(100, 100_000))
        return xml.replace(b"</fmiModelDescription>", b"<a>" * n + b"</a>" * n + b"</fmiModelDescription>"), f"{n} nested"
    if how == "not_utf8":
        i = draw(st.integers(0, len(xml)))
        return xml[:i] + b"\xff\xfe" + xml[i:], "not UTF-8"
    if how == "encoding":
        return xml.replace(b'encoding="UTF-8"', draw(st.sampled_from([b'encoding="nope"', b'encoding="UTF-16"'])), 1), "encoding"
    if how == "truncate":
        return xml[:draw(st.integers(0, len(xml) - 1))], "truncated"
    if how == "version":
        v = draw(st.sampled_from([b"1.0", b"2.0", b"3.0", b"4.0", b"", b"3.0-beta"]))
        return re.sub(rb'fmiVersion="[^"]*"', b'fmiVersion="' + v + b'"', xml, count=1), f"fmiVersion {v!r}"
    data, name = draw(mutations(xml, header=len(xml)))
    return data, name


# --- the reader targets ---------------------------------------------------------------------------------
@st.composite
def archive_cases(draw: Any) -> Case:
    """An FMU archive's bytes mutated, given to ``info`` or ``check``."""
    seed = fmu_seed(draw(st.sampled_from(["fmi2", "fmi3"])), draw(st.sampled_from(["Dahlquist", "Feedthrough"])))
    data, how = draw(mutations(seed, header=len(seed)))
    return Case("fmu-archive", [draw(st.sampled_from(["info", "check"])), "m.fmu"], {"m.fmu": data}, None, how)


@st.composite
def model_description_cases(draw: Any) -> Case:
    """An FMU whose modelDescription.xml is mutated (the rest intact), given to ``info`` or ``check``."""
    files = members(fmu_seed(draw(st.sampled_from(["fmi2", "fmi3"])), draw(st.sampled_from(["Dahlquist", "Feedthrough"]))))
    files["modelDescription.xml"], how = draw(xml_mutations(files["modelDescription.xml"]))
    return Case("model-description", [draw(st.sampled_from(["info", "check"])), "m.fmu"], {"m.fmu": rezip(files)},
                None, how)


@st.composite
def binary_in_archive_cases(draw: Any) -> Case:
    """An FMU whose binary is mutated, checked (``check`` reads it without loading it)."""
    files = members(fmu_seed())
    so = next(k for k in files if k.endswith(".so"))
    files[so], how = draw(mutations(files[so], header=4096))
    return Case("elf-in-archive", ["check", "m.fmu"], {"m.fmu": rezip(files)}, None, how)


@dataclass(frozen=True)
class ByteReader:
    """A reader called directly: ``read(bytes)`` returns a value or raises one of ``clean``."""

    seed: Callable[[], bytes]
    read: Callable[[bytes], Any]
    returns: tuple[type, ...]
    header: int = 4096


def _elf(data: bytes) -> Any:
    from wmr_cosim.cosim.model.binary import library_problem

    return library_problem(data, 2, "co-simulation", platform="linux")


def _pe(data: bytes) -> Any:
    from wmr_cosim.cosim.model.binary import library_problem

    return library_problem(data, 2, "co-simulation", platform="win32")


BYTE_READERS = {"elf": ByteReader(elf_seed, _elf, (str, type(None))),
                "pe": ByteReader(pe_seed, _pe, (str, type(None)), header=1024)}


# --- a results folder -----------------------------------------------------------------------------------
@cache
def results_seed() -> dict[str, bytes]:
    """The files of a results folder of a short run with a requirement (made once, in memory)."""
    import shutil
    import tempfile

    from contract_support import run_cli
    from reference_fmus import fmi2

    work = Path(tempfile.mkdtemp(prefix="contract-seed-"))
    try:
        (work / "s.toml").write_text(f'[experiment]\nstop = 0.05\nstep = 0.01\n[instances.d]\nfmu = "{fmi2("Dahlquist")}"\n'
                                     '[[requirements]]\nname = "small"\nformula = "always d.x < 2"\n', encoding="utf-8")
        o = run_cli(["run", "s.toml", "--out", "r", "--quiet"], work)
        assert o.code == 0, o.stderr
        return {p.name: p.read_bytes() for p in (work / "r").iterdir() if p.is_file()}
    finally:
        shutil.rmtree(work, ignore_errors=True)


@st.composite
def results_cases(draw: Any) -> Case:
    """A results folder with one of its files mutated (or emptied, or gone), given to ``plot``."""
    files = dict(results_seed())
    name = draw(st.sampled_from(["signals.npy", "requirements.npy", "summary.json", "scenario.json"]))
    how = draw(st.sampled_from(["mutate", "mutate", "empty", "remove"]))
    if how == "mutate":
        files[name], how = draw(mutations(files[name], header=256))
    elif how == "empty":
        files[name] = b""
    else:
        del files[name]
    argv = ["plot", "r", "--out", "p.png"] + (["--requirement", "small"] if draw(st.booleans()) else [])
    return Case("results-plot", argv, {f"r/{k}": v for k, v in files.items()}, None, f"{name}: {how}")


@dataclass
class ReaderCase:
    """Bytes for one of :data:`BYTE_READERS`."""

    reader: str
    data: bytes
    mutation: str

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:   # how Hypothesis prints an example: short
        p.text(repr(self))

    def __repr__(self) -> str:
        return f"ReaderCase({self.reader!r}, mutation={self.mutation!r}, {len(self.data)} bytes, head={self.data[:64]!r})"


def reader_cases(name: str) -> st.SearchStrategy[ReaderCase]:
    r = BYTE_READERS[name]
    return mutations(r.seed(), header=r.header).map(lambda dm: ReaderCase(name, dm[0], dm[1]))


def reader_violations(case: ReaderCase, timeout: float) -> list[Any]:
    """The contract of a reader called directly: a value of its type or a CosimError, in time."""
    from contract_support import Violation, call
    from wmr_cosim.cosim import CosimError

    r = BYTE_READERS[case.reader]
    value, o = call(lambda: r.read(case.data), timeout)
    shown = repr(case)
    out = []
    if o.hang:
        out.append(Violation(f"{case.reader} reader: no answer within the time limit", shown))
    elif o.error is not None:
        exc_clean = o.error_type in {c.__name__ for c in (CosimError, *CosimError.__subclasses__())}
        if not exc_clean:
            out.append(Violation(f"{case.reader} reader: {o.error_type} at {o.where}", f"{shown}\n{o.error[-2000:]}"))
    elif not isinstance(value, r.returns):
        out.append(Violation(f"{case.reader} reader: returned a {type(value).__name__}", shown))
    from contract_support import MEMORY_LIMIT_MIB
    if o.memory_mib > MEMORY_LIMIT_MIB:
        out.append(Violation(f"{case.reader} reader: memory grew by {o.memory_mib:.0f} MiB", shown))
    return out


# --- SSP archives and input tables ----------------------------------------------------------------------
@cache
def ssp_seed() -> bytes:
    """An SSP archive of Dahlquist -> Feedthrough written by ``export-ssp`` (made once, in memory)."""
    import shutil
    import tempfile

    from contract_support import run_cli
    from reference_fmus import fmi2

    work = Path(tempfile.mkdtemp(prefix="contract-seed-"))
    try:
        (work / "e.toml").write_text(f'[experiment]\nstop = 0.05\nstep = 0.01\n[instances.d]\nfmu = "{fmi2("Dahlquist")}"\n'
                                     f'[instances.a]\nfmu = "{fmi2("Feedthrough")}"\n[[connections]]\nfrom = "d.x"\n'
                                     'to = "a.Float64_continuous_input"\n', encoding="utf-8")
        o = run_cli(["export-ssp", "e.toml", "--out", "e.ssp"], work)
        assert o.code == 0, o.stderr
        return (work / "e.ssp").read_bytes()
    finally:
        shutil.rmtree(work, ignore_errors=True)


@st.composite
def ssp_cases(draw: Any) -> Case:
    """An SSP archive with its SystemStructure.ssd mutated (or the archive's bytes), given to ``check``."""
    files = members(ssp_seed())
    if draw(st.integers(0, 3)):
        files["SystemStructure.ssd"], how = draw(xml_mutations(files["SystemStructure.ssd"]))
        data = rezip(files)
    else:
        data, how = draw(mutations(ssp_seed(), header=len(ssp_seed())))
    return Case("ssp-archive", ["check", "m.ssp"], {"m.ssp": data}, None, how)


INPUTS_SEED = b"time,Float64_continuous_input,Int32_input,Boolean_input\n0,1,2,0\n0.02,2,3,1\n0.04,-1,0,1\n"


@st.composite
def inputs_cases(draw: Any) -> Case:
    """An input table (CSV) of the Feedthrough FMU mutated, checked or run with ``--input``."""
    from reference_fmus import fmi2

    if draw(st.booleans()):
        data, how = draw(mutations(INPUTS_SEED, header=len(INPUTS_SEED)))
    else:
        cells = draw(st.sampled_from(["nan", "inf", "-inf", "1e999", "", "x", "9223372036854775808", "0x10", " 1",
                                      "1,2", "\"1\"", "true"]))
        row = draw(st.integers(1, 3))
        lines = INPUTS_SEED.split(b"\n")
        parts = lines[row].split(b",")
        parts[draw(st.integers(0, len(parts) - 1))] = cells.encode()
        lines[row] = b",".join(parts)
        data, how = b"\n".join(lines), f"a cell {cells!r}"
    cmd = draw(st.sampled_from(["check", "run"]))
    argv = [cmd, str(fmi2("Feedthrough")), "--input", "in.csv", "--stop", "0.05", "--step", "0.01"]
    argv += ["--out", "out", "--quiet"] if cmd == "run" else []
    return Case("inputs-csv", argv, {"in.csv": data}, None, how)

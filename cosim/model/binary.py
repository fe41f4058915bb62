"""What an FMU's binary is, read from its bytes without loading it: a shared library of this platform
(ELF: 64-bit, little-endian, a shared object for x86-64 that is not a position-independent executable;
PE: a DLL for x64) that exports the FMI functions an interface needs.  ``check`` refuses a binary the loader would refuse, before any instance
is made, without running the library's code (loading it would run its constructors)."""
from __future__ import annotations

import os
import struct
import sys
from typing import Iterable

#: The FMI functions each interface's binary must export (a binary FMU's functions are not prefixed): the
#: ones the master calls first and at every step of that interface.
REQUIRED = {
    (2, "co-simulation"): ("fmi2Instantiate", "fmi2DoStep"),
    (2, "model-exchange"): ("fmi2Instantiate", "fmi2GetDerivatives"),
    (3, "co-simulation"): ("fmi3InstantiateCoSimulation", "fmi3DoStep"),
    (3, "model-exchange"): ("fmi3InstantiateModelExchange", "fmi3GetContinuousStateDerivatives"),
    (3, "scheduled-execution"): ("fmi3InstantiateScheduledExecution", "fmi3ActivateModelPartition"),
}

_ELF_MACHINES = {3: "x86 (32-bit)", 40: "ARM", 62: "x86-64", 183: "AArch64", 243: "RISC-V"}
_ELF_TYPES = {1: "a relocatable object", 2: "an executable", 3: "a shared object", 4: "a core file"}
_ET_DYN, _EM_X86_64, _SHT_DYNSYM = 3, 62, 11
_PT_DYNAMIC, _DT_NULL, _DT_FLAGS_1, _DF_1_PIE = 2, 0, 0x6FFFFFFB, 0x08000000
#: The sizes of an ELF64 section header, program header, symbol and dynamic entry [bytes].
_SHDR, _PHDR, _SYM, _DYN = 64, 56, 24, 16


def library_problem(data: bytes, fmi: int, interface: str, platform: str = sys.platform) -> str | None:
    """None if ``data`` is a shared library the loader of ``platform`` (``sys.platform``) can load and
    that exports the FMI functions of ``interface`` (FMI version ``fmi``), else why not (a phrase).  On a
    platform whose format is not read here (macOS), None.  The work is linear in the size of ``data``
    whatever its content: each header, table and string is read once, at an offset checked against the
    file's length."""
    if platform.startswith("linux"):
        return _elf_problem(data, REQUIRED[(fmi, interface)])
    if platform == "win32":
        return _pe_problem(data)
    return None


def _elf_problem(data: bytes, required: tuple[str, ...]) -> str | None:
    if data[:4] != b"\x7fELF":
        return f"not an ELF shared library (it begins {data[:8]!r})"
    if len(data) < 64:
        return f"a truncated ELF file ({len(data)} bytes)"
    if data[4] != 2 or data[5] != 1:
        return "not a 64-bit little-endian ELF file (class %d, data %d)" % (data[4], data[5])
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    if e_machine != _EM_X86_64:
        return f"an ELF file for {_ELF_MACHINES.get(e_machine, f'machine {e_machine}')}, not x86-64"
    if e_type != _ET_DYN:
        return f"{_ELF_TYPES.get(e_type, f'an ELF file of type {e_type}')}, not a shared object"
    pie = _elf_pie(data)
    if pie is None:
        return "a truncated or malformed ELF file (its program headers or dynamic section lie outside it)"
    if pie:
        return "a position-independent executable (DF_1_PIE), not a shared object"
    exported = _elf_exports(data, required)
    if isinstance(exported, str):
        return f"a truncated or malformed ELF file ({exported})"
    missing = [f for f in required if f not in exported]
    if missing:
        return f"exports no {', '.join(missing)}"
    return None


def _elf_pie(data: bytes) -> bool | None:
    """Whether an ELF64 shared object is a position-independent executable (its dynamic section's
    DT_FLAGS_1 has DF_1_PIE: the flag by which the loader refuses to load it as a library), or None if its
    program headers or dynamic section do not fit in it."""
    (phoff,) = struct.unpack_from("<Q", data, 32)
    phentsize, phnum = struct.unpack_from("<HH", data, 54)
    if phnum == 0:
        return False
    if phentsize < _PHDR or phoff + phnum * phentsize > len(data):
        return None
    for i in range(phnum):
        p_type, _, p_offset, _, _, p_filesz = struct.unpack_from("<IIQQQQ", data, phoff + i * phentsize)
        if p_type != _PT_DYNAMIC:
            continue
        if p_offset + p_filesz > len(data):
            return None
        for tag, value in struct.iter_unpack("<qQ", data[p_offset:p_offset + p_filesz - p_filesz % _DYN]):
            if tag == _DT_NULL:
                break
            if tag == _DT_FLAGS_1:
                return bool(value & _DF_1_PIE)
        return False   # the loader reads the first PT_DYNAMIC only
    return False


def _elf_exports(data: bytes, wanted: Iterable[str]) -> set[str] | str:
    """Which of the names ``wanted`` an ELF64 file defines in its dynamic symbol table, or what is
    malformed (a phrase).  Linear in the file: the string table is searched once for each wanted name
    (as a whole, NUL-terminated string, where a symbol's name may begin), then each symbol's name offset is
    looked up among those places; no symbol's name is read."""
    (shoff,) = struct.unpack_from("<Q", data, 40)
    shentsize, shnum = struct.unpack_from("<HH", data, 58)
    if shnum == 0:
        return set()
    if shentsize < _SHDR or shoff + shnum * shentsize > len(data):
        return "its section headers lie outside it"
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
    dynsym = [s for s in sections if s[1] == _SHT_DYNSYM]
    if not dynsym:
        return set()
    if len(dynsym) > 1:
        return f"{len(dynsym)} dynamic symbol tables"
    _, _, _, _, off, size, link, _, _, entsize = dynsym[0]
    if link >= shnum or entsize < _SYM:
        return "its dynamic symbol table names no string table"
    str_off, str_size = sections[link][4], sections[link][5]
    if off + size > len(data) or str_off + str_size > len(data):
        return "its dynamic symbol table lies outside it"
    strtab = data[str_off:str_off + str_size]
    at: dict[int, str] = {}   # offset in the string table -> the wanted name that begins there
    for name in wanted:
        key, start = name.encode("ascii") + b"\0", 0
        while (i := strtab.find(key, start)) >= 0:
            at[i] = name
            start = i + 1
    found: set[str] = set()
    if not at:
        return found
    table = data[off:off + size - size % entsize]
    if entsize == _SYM:
        symbols = struct.iter_unpack("<IBBHQQ", table)
    else:
        symbols = (struct.unpack_from("<IBBHQQ", table, i) for i in range(0, len(table), entsize))
    for st_name, _, _, st_shndx, _, _ in symbols:
        if st_shndx != 0 and st_name in at:   # defined here
            found.add(at[st_name])
    return found


def _pe_problem(data: bytes) -> str | None:
    if data[:2] != b"MZ" or len(data) < 64:
        return f"not a Windows DLL (it begins {data[:8]!r})"
    (pe,) = struct.unpack_from("<I", data, 0x3C)
    if data[pe:pe + 4] != b"PE\0\0" or pe + 24 > len(data):
        return "not a Windows DLL (no PE header)"
    machine, _, _, _, _, _, characteristics = struct.unpack_from("<HHIIIHH", data, pe + 4)
    if machine != 0x8664:
        return f"a Windows binary for machine 0x{machine:04x}, not x64"
    if not characteristics & 0x2000:
        return "a Windows executable, not a DLL"
    return None


def load_failure(exc: BaseException, unzipdir: str) -> str:
    """The loader's reason for refusing an FMU's binary, from FMPy's exception, in one line with the
    paths inside the extracted archive made relative to it."""
    return " ".join(str(exc).replace(unzipdir.rstrip(os.sep) + os.sep, "").split())


#: Why an instance of a pythonfmu FMU in this process steps alone when instances step at once.
PYTHON_FMU = ("a pythonfmu FMU: its step runs Python code, which holds the GIL (isolate = true steps it in a "
              "process of its own)")


def runs_python(members: Iterable[str]) -> bool:
    """Whether an FMU whose files are ``members`` (paths inside it, '/'-separated) runs Python code in its
    steps: a pythonfmu FMU, whose binaries hold pythonfmu's exporter library and whose resources name the
    module of its slave."""
    for m in members:
        if m == "resources/slavemodule.txt" or (m.startswith("binaries/") and
                                                 m.rsplit("/", 1)[-1].startswith("libpythonfmu-export")):
            return True
    return False

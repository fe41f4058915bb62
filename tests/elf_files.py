"""ELF64 files written byte by byte for the readers of binaries (cosim/model/binary.py): a shared object's
header, string table, dynamic symbol table and section headers, and nothing else, with any field as a
hostile file would give it."""
from __future__ import annotations

import struct


def elf_file(strtab: bytes, symbols: list[tuple[int, int]], dynsym_sections: int = 1, sym_off: int | None = None,
             e_type: int = 3) -> bytes:
    """A minimal ELF64 x86-64 file of type ``e_type`` (3: a shared object) with a string table ``strtab``
    and a dynamic symbol table of ``symbols`` (name offset, section index: 0 undefined), named by
    ``dynsym_sections`` section headers; ``sym_off`` places the symbol table elsewhere (outside the file)."""
    header_size = 64
    sym = b"".join(struct.pack("<IBBHQQ", name, 0x12, 0, shndx, 0, 0) for name, shndx in symbols)
    str_at = header_size
    sym_at = str_at + len(strtab)
    sh_at = sym_at + len(sym)
    sections = [bytes(64), struct.pack("<IIQQQQIIQQ", 0, 3, 0, 0, str_at, len(strtab), 0, 0, 1, 0)]
    sections += [struct.pack("<IIQQQQIIQQ", 0, 11, 2, 0, sym_at if sym_off is None else sym_off, len(sym), 1, 1, 8,
                             24)] * dynsym_sections
    ident = b"\x7fELF" + bytes([2, 1, 1]) + bytes(9)
    head = ident + struct.pack("<HHIQQQIHHHHHH", e_type, 62, 1, 0, 0, sh_at, 0, 64, 56, 0, 64, len(sections), 0)
    return head + strtab + sym + b"".join(sections)

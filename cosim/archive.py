"""Safe extraction of zip archives (FMU, SSP): every entry is checked before anything is written.

Refused: absolute paths, drive letters, '..' components, backslash tricks, and symbolic links (FMPy's
extract refuses only absolute paths; Python's zipfile silently rewrites '../x' to 'x'; a symlink entry
becomes a plain file).
"""
from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path, PurePosixPath

from .errors import FmuLoadError


def check_archive(path: str | os.PathLike) -> list[zipfile.ZipInfo]:
    """The archive's entries, or FmuLoadError naming the archive and the first unsafe entry."""
    path = Path(path)
    if not path.is_file():
        raise FmuLoadError(f"{path}: file not found")
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise FmuLoadError(f"{path}: not a zip archive ({exc})") from None
    with zf:
        infos = zf.infolist()
    check_entries(str(path), infos)
    return infos


def check_entries(label: str, infos: list[zipfile.ZipInfo]) -> None:
    """FmuLoadError naming ``label`` and the first entry that is absolute, climbs out with '..' or is a link."""
    for info in infos:
        name = info.filename
        p = PurePosixPath(name.replace("\\", "/"))
        mode = (info.external_attr >> 16) & 0xFFFF
        if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
            raise FmuLoadError(f"{label}: refused: entry '{name}' has an absolute path")
        if ".." in p.parts:
            raise FmuLoadError(f"{label}: refused: entry '{name}' would extract outside its folder")
        if stat.S_ISLNK(mode):
            raise FmuLoadError(f"{label}: refused: entry '{name}' is a symbolic link")


def safe_extract(path: str | os.PathLike, dest: str | os.PathLike) -> Path:
    """Check the whole archive, then extract it into ``dest`` (created); returns ``dest``."""
    check_archive(path)
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    root = dest.resolve()
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            target = (dest / info.filename).resolve()
            if root != target and root not in target.parents:  # belt and braces
                raise FmuLoadError(f"{path}: refused: entry '{info.filename}' would extract outside its folder")
        zf.extractall(dest)
    return dest

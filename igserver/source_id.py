"""Which source made a picture or a benchmark: a short digest of the package's files (Python, GLSL,
scenes, tables, assets: everything that decides what is rendered).

Pictures and timings are made on other machines from a copy of a working tree, where there may be no
git to ask. Two machines' pictures of one scene can differ by their drivers or by their code; the
digest, printed with every picture and stored in every benchmark report, tells which. To find the
commit of a digest: ``git checkout <commit> && igserver source-id`` (or compare it with the digest of
the tree at hand)."""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).parent


def digest(root: Path) -> str:
    """12 hex digits of SHA-1 over the relative paths and bytes of the files under ``root`` (compiled
    Python left out)."""
    files = sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc")
    sha = hashlib.sha1()
    for path in files:
        sha.update(path.relative_to(root).as_posix().encode() + b"\0")
        sha.update(path.read_bytes())
        sha.update(b"\0")
    return sha.hexdigest()[:12]


@lru_cache(maxsize=1)
def source_id() -> str:
    """The package's digest (~3 MB read, a few ms; once per process)."""
    return digest(ROOT)

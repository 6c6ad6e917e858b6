"""Named assets: the host names an asset, the server decides where its file is.

The host never sends a file-system path (docs/design.md#service). An asset is ``(kind, name)``: ``kind`` is a
folder (``models``, ``profiles``), ``name`` a plain file name matching ``ASSET_NAME_PATTERN``.
Files are looked up first in the configured asset directory (``IGSERVER_ASSETS``, else none),
then in the assets shipped with the package (this folder). A name resolves only to a regular
file that really lies inside its kind's folder: path separators, ``..``, hidden names, symlinks
that leave the folder, devices, FIFOs and sockets are refused, and files over ``MAX_ASSET_BYTES``
are refused before they are opened.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

ASSET_KINDS = ("models", "profiles", "bathymetry")
ASSET_NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$"
MAX_ASSET_BYTES = 256 * 1024 * 1024
_NAME_RE = re.compile(ASSET_NAME_PATTERN)
PACKAGE_ASSETS = Path(__file__).resolve().parent


class AssetError(ValueError):
    """An asset name that cannot be served; the message is safe to show the client (no paths)."""


def asset_roots() -> list[Path]:
    """Directories searched, first match wins: the configured one, then the packaged assets."""
    roots = []
    configured = os.environ.get("IGSERVER_ASSETS")
    if configured:
        roots.append(Path(configured).resolve())
    roots.append(PACKAGE_ASSETS)
    return roots


def check_name(name: str) -> str:
    if not isinstance(name, str) or not _NAME_RE.match(name) or ".." in name:
        raise AssetError(f"asset name {name!r} is not a plain name (letters, digits, '_', '.', '-'; max 64)")
    return name


def resolve_asset(kind: str, name: str, suffixes: tuple[str, ...] = ()) -> Path:
    """The regular file of asset ``name`` of ``kind``; ``suffixes`` are tried when ``name`` has none.

    Raises AssetError (message without server paths) when it does not exist or is not allowed.
    """
    if kind not in ASSET_KINDS:
        raise AssetError(f"unknown asset kind {kind!r}")
    check_name(name)
    candidates = [name] if not suffixes or Path(name).suffix else [name + s for s in suffixes]
    for root in asset_roots():
        folder = (root / kind).resolve()
        for candidate in candidates:
            path = folder / candidate
            try:
                real = path.resolve(strict=True)
            except (FileNotFoundError, RuntimeError, OSError):
                continue
            if real.parent != folder:
                raise AssetError(f"asset {name!r} points outside the {kind} directory")
            st = os.stat(real)  # after resolve: the target, not a link
            if not stat.S_ISREG(st.st_mode):
                raise AssetError(f"asset {name!r} is not a regular file")
            if st.st_size > MAX_ASSET_BYTES:
                raise AssetError(f"asset {name!r} is larger than {MAX_ASSET_BYTES // 2**20} MiB")
            return real
    raise AssetError(f"no {kind.removesuffix('s')} asset named {name!r} (available: {', '.join(list_assets(kind)) or 'none'})")


def list_assets(kind: str) -> list[str]:
    """Names of the assets of ``kind`` available now (configured directory first)."""
    names: dict[str, None] = {}
    for root in asset_roots():
        folder = root / kind
        if not folder.is_dir():
            continue
        for entry in sorted(folder.iterdir()):
            if _NAME_RE.match(entry.name) and entry.is_file() and not entry.name.startswith("_"):
                names.setdefault(entry.name, None)
    return list(names)

"""The source digest printed with pictures and stored in benchmark reports (igserver/source_id.py):
pictures made on two machines compare only when it is the same."""

from __future__ import annotations

import re

from igserver.cli import main
from igserver.source_id import ROOT, digest, source_id


def test_digest_follows_content_names_and_ignores_bytecode(tmp_path):
    (tmp_path / "render").mkdir()
    (tmp_path / "render" / "march.frag.glsl").write_text("void main() {}\n")
    (tmp_path / "profiles.py").write_text("T = 1520.0\n")
    first = digest(tmp_path)
    assert re.fullmatch(r"[0-9a-f]{12}", first) and digest(tmp_path) == first
    (tmp_path / "__pycache__").mkdir()
    (tmp_path / "__pycache__" / "profiles.cpython-312.pyc").write_bytes(b"\0" * 16)
    (tmp_path / "render" / "x.pyc").write_bytes(b"\1")
    assert digest(tmp_path) == first  # compiled Python is not source
    (tmp_path / "profiles.py").write_text("T = 2800.0\n")  # one value in one file
    changed = digest(tmp_path)
    assert changed != first
    (tmp_path / "profiles.py").rename(tmp_path / "render" / "profiles.py")  # same bytes, another place
    assert digest(tmp_path) not in (first, changed)


def test_package_digest_and_command(capsys):
    assert source_id() == digest(ROOT)
    assert main(["source-id"]) == 0
    assert capsys.readouterr().out.strip() == source_id()

"""Fuzz the served OpenAPI document with schemathesis, bounded in time: no 5xx, answers as documented.

In the suite: 15 s, the operations that do not wait for a render (a frame of a fuzzed state can take a
table precompute of tens of seconds on llvmpipe: that is the render budget's business, not the edge's).
The longer run, over every operation (README, "Fuzzing"):

    .venv/bin/igserver serve --scene sky_only --port 8711 --width 64 --height 36 &
    .venv/bin/st run http://127.0.0.1:8711/openapi.json --checks not_a_server_error,status_code_conformance,\\
        content_type_conformance,response_headers_conformance,unsupported_method,allow_header_conformance \\
        --exclude-path /v1/stream.mjpg --request-timeout 120 --max-time 600 -w 1
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

CHECKS = ("not_a_server_error,status_code_conformance,content_type_conformance,response_headers_conformance,"
          "unsupported_method,allow_header_conformance")
FUZZ_SECONDS = 15


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    # fuzzed atmospheres precompute tables: keep them out of the user's cache
    cache = tmp_path_factory.mktemp("fuzz-cache")
    previous = os.environ.get("IGSERVER_CACHE")
    os.environ["IGSERVER_CACHE"] = str(cache)
    scene = Scene.model_validate({"camera": {"width": 64, "height": 36}, "atmosphere": {"model": "gradient"}})
    try:
        with LoopbackServer(scene, ServerSettings(keepalive_s=5.0, max_fps=10)) as srv:
            yield srv
    finally:
        if previous is None:
            os.environ.pop("IGSERVER_CACHE", None)
        else:
            os.environ["IGSERVER_CACHE"] = previous


def test_schemathesis_finds_no_server_error(server, tmp_path):
    st = Path(sys.executable).with_name("st")
    command = [
        str(st), "run", f"{server.url}/openapi.json", "--checks", CHECKS,
        "--exclude-path-regex", r"^/v1/(stream\.mjpg|frame|render)$",
        "--max-time", str(FUZZ_SECONDS), "-w", "1", "--phases", "examples,coverage,fuzzing",
        "--request-timeout", "30", "--generation-database", "none", "--no-color",
    ]
    result = subprocess.run(command, capture_output=True, text=True, timeout=FUZZ_SECONDS + 120, cwd=tmp_path)
    output = result.stdout + result.stderr
    counts = re.search(r"(\d+) generated", output)
    assert counts, output[-3000:]
    generated = int(counts.group(1))
    print(f"schemathesis: {generated} test cases")  # the count the closing note asks for
    assert "not_a_server_error" not in output and "Server error" not in output, output[-4000:]
    assert result.returncode == 0, output[-4000:]
    assert generated >= 50  # independent floor: ~15 operations, a few cases each, even on a loaded machine

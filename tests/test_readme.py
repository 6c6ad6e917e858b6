"""The README's commands and programs, run as written, so the README cannot drift from the product.

Every line of every ```bash block runs from the repository root with `.venv/bin` first on PATH; every
```python block runs with the virtual environment's Python; every ```toml block is loaded as a scene file.
Commands and programs that talk to a running server get one: this module starts `igserver serve` on a
free loopback port (a small frame size, so frames are cheap) and points `IGSERVER_URL` at it, which
`igclient` and the README's host program read, as the README says.

Where a command is not simply run, the reason:

- `bash scripts/run.sh` starts a server that runs until stopped. It runs with `IGSERVER_PORT` (a setting the
  README documents for another port) on a free port until it prints the viewer's address, then is stopped.
- `bash scripts/test.sh` is the suite this test belongs to: it runs with `--collect-only -q` appended (its
  arguments go to pytest), so its installation steps run and every test module is imported and collected,
  without running the suite inside itself.
- `igserver bench` and `igserver quality` over the README's scenes and presets take from several minutes to
  an hour on two cores. They are validated dry: the command with `--help` appended must succeed and its
  help must name every flag the README uses, and every scene a `--scenes` list names must load.

The clients/ host program the README points to runs too, against the same server. The README's and the
docs pages' links resolve, and every docs/design.md section a code comment cites exists.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
VENV_BIN = ROOT / ".venv" / "bin"
COMMAND_TIMEOUT_S = 300  # one command: a render spawns its own render process and compiles its shaders
SERVER_START_S = 300  # a first start with an empty table cache precomputes the atmosphere (~1 min on 2 cores)
DRY_RUN = {"bench", "quality"}  # igserver subcommands validated dry (module docstring)


def readme_blocks(language: str) -> list[str]:
    text = README.read_text()
    return [m.group(2) for m in re.finditer(r"^```(\w+)\n(.*?)^```", text, re.S | re.M) if m.group(1) == language]


def bash_commands() -> list[str]:
    """Each command of the bash blocks: continuation lines joined, comment-only and blank lines dropped."""
    commands = []
    for block in readme_blocks("bash"):
        for line in block.replace("\\\n", " ").splitlines():
            if shlex.split(line, comments=True):
                commands.append(line.strip())
    return commands


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def environment(**extra: str) -> dict:
    env = dict(os.environ, PATH=f"{VENV_BIN}{os.pathsep}{os.environ.get('PATH', '')}", **extra)
    env.pop("IGSERVER_TOKEN", None)  # the servers here run on loopback without a token
    return env


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def wait_for_line(proc: subprocess.Popen, pattern: str, timeout: float) -> str:
    """Read the process's output until a line matches; what it printed, for the failure message."""
    seen, deadline = [], time.monotonic() + timeout
    os.set_blocking(proc.stdout.fileno(), False)
    buffer = b""
    while time.monotonic() < deadline:
        chunk = proc.stdout.read()
        if chunk:
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                seen.append(line.decode(errors="replace"))
                if re.search(pattern, seen[-1]):
                    return "\n".join(seen)
        elif proc.poll() is not None:
            break
        else:
            time.sleep(0.2)
    pytest.fail(f"no line matching {pattern!r} within {timeout} s (exit {proc.poll()}):\n" + "\n".join(seen[-30:]))


@pytest.fixture(scope="module")
def server_url():
    port = free_port()
    proc = subprocess.Popen([str(VENV_BIN / "igserver"), "serve", "--scene", "demo", "--port", str(port),
                             "--width", "160", "--height", "90"], cwd=ROOT, env=environment(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + SERVER_START_S
        while True:
            try:
                if httpx.get(f"{url}/v1/ready", timeout=5).json().get("ready"):
                    break
            except httpx.HTTPError:
                pass
            assert proc.poll() is None, f"igserver serve exited: {proc.stdout.read().decode(errors='replace')}"
            assert time.monotonic() < deadline, f"igserver serve not ready after {SERVER_START_S} s"
            time.sleep(0.5)
        yield url
    finally:
        stop(proc)


def run(command: str, env: dict, cwd: Path = ROOT, timeout: float = COMMAND_TIMEOUT_S) -> subprocess.CompletedProcess:
    result = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True,
                            timeout=timeout)
    assert result.returncode == 0, f"{command}\nexit {result.returncode}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


def check_server_command(command: str) -> None:
    """A command that starts a long-running server: run it on a free port until it prints the viewer URL."""
    port = free_port()
    proc = subprocess.Popen(["bash", "-c", command], cwd=ROOT, env=environment(IGSERVER_PORT=str(port)),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        wait_for_line(proc, rf"viewer at http://127\.0\.0\.1:{port}/", SERVER_START_S)
    finally:
        stop(proc)


def check_dry(argv: list[str]) -> None:
    """`igserver bench|quality …` validated without the minutes it takes (module docstring)."""
    from igserver.scene import load_scene

    result = run(shlex.join([*argv, "--help"]), environment())
    flags = [a.split("=")[0] for a in argv if a.startswith("--")]
    missing = [f for f in flags if f not in result.stdout]
    assert not missing, f"{shlex.join(argv)}: flags not in its --help: {missing}"
    for i, arg in enumerate(argv[:-1]):
        if arg == "--scenes":
            for name in argv[i + 1].split(","):
                load_scene(name)


@pytest.mark.parametrize("command", bash_commands(), ids=lambda c: shlex.join(shlex.split(c, comments=True))[:70])
def test_readme_shell_command(command, request):
    argv = shlex.split(command, comments=True)
    command = shlex.join(argv)  # without its comment; the README's commands use no expansions
    if argv[:2] == ["bash", "scripts/run.sh"] or argv[1:2] == ["serve"]:
        check_server_command(command)
    elif argv[:2] == ["bash", "scripts/test.sh"]:
        result = run(f"{command} --collect-only -q", environment())
        # exit 0 means every module imported and collected; this file among them, with its tests
        assert re.search(r"^tests/test_readme\.py: \d+$", result.stdout, re.M), result.stdout[-2000:]
    elif Path(argv[0]).name == "igserver" and argv[1] in DRY_RUN:
        check_dry(argv)
    elif Path(argv[0]).name == "igclient":
        run(command, environment(IGSERVER_URL=request.getfixturevalue("server_url")))
    else:
        run(command, environment())


@pytest.mark.parametrize("index", range(len(readme_blocks("python"))))
def test_readme_python_block(index, server_url, tmp_path):
    program = tmp_path / "readme_block.py"
    program.write_text(readme_blocks("python")[index])
    run(f"{shlex.quote(sys.executable)} {program}", environment(IGSERVER_URL=server_url), cwd=tmp_path)


def test_readme_host_program_in_clients(server_url, tmp_path):
    """The runnable copy the README links to, as clients/README.md runs it (fewer frames)."""
    out = tmp_path / "frame.jpg"
    run(f"{shlex.quote(sys.executable)} clients/host_loop.py --url {server_url} --frames 3 --out {out}", environment())
    assert out.read_bytes()[:2] == b"\xff\xd8"  # a JPEG


@pytest.mark.parametrize("index", range(len(readme_blocks("toml"))))
def test_readme_scene_file_loads(index, tmp_path):
    from igserver.scene import load_scene

    path = tmp_path / "scene.toml"
    path.write_text(readme_blocks("toml")[index])
    load_scene(str(path))


def anchors(path: Path) -> set[str]:
    """The anchors a Markdown page offers: GitHub's heading slugs and explicit <a id="...">."""
    text = path.read_text()
    slugs = {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
             for h in re.findall(r"^#+ (.*)$", text, re.M)}
    return slugs | set(re.findall(r'<a id="([^"]+)"', text))


def test_readme_links_resolve():
    """Every relative link of the README and of the docs/ pages names a file of the repository, and its
    anchor a heading (or an <a id>) there."""
    for page in [README, ROOT / "clients" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target, anchor in re.findall(r"\]\(([^)#\s]*)(?:#([^)\s]*))?\)", page.read_text()):
            if "://" in target or target.startswith("mailto:"):
                continue
            path = (page.parent / target) if target else page
            assert path.exists(), f"{page.relative_to(ROOT)} links to a missing {target}"
            if anchor and path.suffix == ".md":
                assert anchor in anchors(path), f"{page.relative_to(ROOT)} links to {target}#{anchor}: no such heading"


def test_clients_are_not_in_the_server_package():
    """clients/ holds example host programs to copy, not server code: the wheel's package discovery
    (pyproject.toml) must not pick it up."""
    import tomllib

    from setuptools import find_packages

    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]
    packages = find_packages(str(ROOT), include=find.get("include", ["*"]), exclude=find.get("exclude", ()))
    assert packages and all(p == "igserver" or p.startswith("igserver.") for p in packages), packages


def test_code_references_to_the_design_resolve():
    """Comments cite the design as docs/design.md#section: each section they name exists."""
    cited = set()
    for path in [*(ROOT / "igserver").rglob("*.py"), *(ROOT / "igserver").rglob("*.glsl"), *(ROOT / "tests").glob("*.py")]:
        if path == Path(__file__).resolve():
            continue
        cited |= {("docs/design.md", m) for m in re.findall(r"docs/design\.md#([\w-]+)", path.read_text())}
    assert ("docs/design.md", "water") in cited  # the pattern still finds the comments
    for doc, anchor in cited:
        assert anchor in anchors(ROOT / doc), f"a comment cites {doc}#{anchor}: no such section"

#!/usr/bin/env bash
# Install what igserver needs: the Mesa EGL system packages (when missing and we are root) and a
# project-local virtual environment (.venv) with the pinned Python dependencies. Idempotent: a
# second run with nothing to do takes about a second. Used by the quick start, CI and the Dockerfiles.
# Environment: IGSERVER_EXTRAS (default "test,quality,cluster": the tests draw the quality report's plots and
# run a local Ray cluster too; empty for a runtime-only install, as the Docker image does),
# IGSERVER_EDITABLE (default 1; 0 installs a regular, non-editable copy into .venv).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

mesa_packages="libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"
missing=""
if command -v dpkg-query >/dev/null 2>&1; then
  for p in $mesa_packages; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing="$missing $p"
  done
fi
if [ -n "$missing" ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "bootstrap: installing Mesa EGL packages:$missing" >&2
    # shellcheck disable=SC2086  # a list of package names, split on purpose
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing >&2
  else
    echo "bootstrap: missing system packages:$missing (install them as root: apt-get install$missing)" >&2
  fi
fi

python="${PYTHON:-python3}"
stamp=".venv/.installed"
if [ ! -x .venv/bin/python ]; then
  "$python" -m venv .venv
fi
extras="${IGSERVER_EXTRAS-test,quality,cluster}"
target="."
[ -n "$extras" ] && target=".[$extras]"
editable="-e"
[ "${IGSERVER_EDITABLE:-1}" = 0 ] && editable=""
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "bootstrap: installing Python dependencies into .venv (${target}${editable:+, editable})" >&2
  # shellcheck disable=SC2086  # $editable is empty or one flag
  .venv/bin/python -m pip install -q --disable-pip-version-check $editable "$target" 2>&1 \
    | grep -v "is ignored: it is neither" >&2 || true
  .venv/bin/python -c "import igserver, moderngl, fastapi" || { echo "bootstrap: install failed" >&2; exit 1; }
  touch "$stamp"
fi

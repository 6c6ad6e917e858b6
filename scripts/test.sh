#!/usr/bin/env bash
# Quick start, command 2: run the test suite (renders tiny frames on llvmpipe through EGL).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
cd "$root"
exec .venv/bin/python -m pytest -q "$@"

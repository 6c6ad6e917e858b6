#!/usr/bin/env bash
# Quick start, command 1: start the IG on its built-in demo scene and print where to watch it.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
exec "$root/.venv/bin/igserver" serve --scene demo "$@"

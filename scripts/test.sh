#!/usr/bin/env bash
# Quick start, command 2: run the test suite (renders tiny frames on llvmpipe through EGL).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
# the viewer is tested in a real browser: Debian's headless Chromium (installed when root, like Mesa)
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "test.sh: installing chromium (viewer tests)" >&2
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >&2; } \
      || echo "test.sh: could not install chromium: the viewer browser tests will be skipped" >&2
  else
    echo "test.sh: chromium missing: the viewer browser tests will be skipped (apt-get install chromium)" >&2
  fi
fi
# the CIGI packets are cross-checked against Wireshark's dissector: Debian's tshark (installed when root)
if ! command -v tshark >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "test.sh: installing tshark (CIGI cross-check)" >&2
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends tshark >&2; } \
    || echo "test.sh: could not install tshark: the CIGI cross-check will be skipped" >&2
fi
# the shaders are checked by the Khronos reference compiler as well as Mesa's: Debian's glslang-tools
if ! command -v glslangValidator >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "test.sh: installing glslang-tools (shader check)" >&2
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends glslang-tools >&2; } \
    || echo "test.sh: could not install glslang-tools: the reference compiler's check will be skipped" >&2
fi
cd "$root"
exec .venv/bin/python -m pytest -q "$@"

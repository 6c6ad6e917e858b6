#!/usr/bin/env bash
# Mutation testing (mutmut) of the modules that carry the protocol's promises and the GL-free physics
# ([tool.mutmut] in pyproject.toml: scene model and patches, state store, codec, problems, frame graph,
# fade/flicker, fire lights, frame lights, astro, water), against the fast in-process GL-free tests
# (-m "not gl and not process"). Workers fork from a server that has only collected the tests
# (process_isolation = "forkserver"): forked from the stats run, they would inherit its lru_caches.
# Slow (minutes to an hour on 2 cores), so not part of CI. Each mutant runs only the tests that reach its
# function; results are kept in mutants/ and a re-run only re-tests what changed.
#
#   bash scripts/mutation.sh                 # run (time box: MUTATION_TIME_BOX seconds, default 3600)
#   bash scripts/mutation.sh "igserver.water.spectrum.*"   # one module (mutant names, fnmatch patterns)
#   bash scripts/mutation.sh --report        # per-module kill rates and the surviving mutants' names
#   .venv/bin/mutmut show NAME               # the diff of one mutant
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/bootstrap.sh
.venv/bin/python -c "import mutmut" 2>/dev/null || .venv/bin/python -m pip install -q -e ".[test,quality,mutation]"
unset PYTHONPATH  # the mutated copy in mutants/ must be the one imported
if [ "${1:-}" != "--report" ]; then
  timeout "${MUTATION_TIME_BOX:-3600}" .venv/bin/mutmut run --max-children "${MUTATION_JOBS:-$(nproc)}" "$@" || \
    echo "mutation: stopped (time box or failure); results so far below" >&2
fi
.venv/bin/python scripts/mutation_report.py --survivors mutants

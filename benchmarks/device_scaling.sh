#!/usr/bin/env bash
# bench_scaling.py on a lent machine (issue 41's 16-core goals), in one call.
#
# The machine has Python with numpy/scipy/pandas/pyyaml but not dask, rasterio, rioxarray,
# pydantic...: those travel as wheels in .whl/ (ignored through .git/info/exclude) and are installed
# into /tmp/site. Arguments after the script go to bench_scaling.py. The whole log goes to
# $OUT/scaling.log (or ./scaling.log without $OUT). BRDFCORR_SRC: a folder holding the brdfcorr package
# to measure (say a `git archive` of a commit), in place of the working tree's.
#
#   bash benchmarks/device_scaling.sh --cores 1 16 8 4 2 --cluster-workers 0
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
LOG=${OUT:-.}/scaling.log
SITE=${SITE:-/tmp/site}

{
  echo "== $(date -u +%FT%TZ) $(uname -srm)"
  echo "cores: nproc $(nproc), affinity $($PY -c 'import os; print(len(os.sched_getaffinity(0)))')"
  grep -m1 "model name" /proc/cpuinfo
  free -g | head -2
  df -h /tmp | tail -1
  command -v taskset || echo "NO taskset"
  $PY -V
} 2>&1 | tee "$LOG"

if ls .whl/*.whl >/dev/null 2>&1; then
  $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" .whl/*.whl \
    2>&1 | tail -3 | tee -a "$LOG" || exit 1
  export PYTHONPATH="$SITE:${BRDFCORR_SRC:-$PWD}${PYTHONPATH:+:$PYTHONPATH}"
else
  export PYTHONPATH="${BRDFCORR_SRC:-$PWD}${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONUNBUFFERED=1

$PY -P - <<'EOF' 2>&1 | tee -a "$LOG" || exit 1
import dask, numpy, pandas, pydantic, pyproj, rasterio, rioxarray, scipy, xarray
import brdfcorr, brdfcorr.tasks.correct  # noqa: F401
print("brdfcorr from", brdfcorr.__file__)
print("versions:", {m.__name__: m.__version__ for m in (numpy, scipy, pandas, xarray, dask, rasterio, rioxarray,
                                                         pydantic, pyproj)}, "GDAL", rasterio.__gdal_version__)
EOF

start=$(date +%s)
$PY benchmarks/bench_scaling.py "$@" 2>&1 | tee -a "$LOG"
rc=${PIPESTATUS[0]}
echo "== bench_scaling exit $rc after $(( $(date +%s) - start )) s" | tee -a "$LOG"
exit "$rc"

# Issue 11, round 8: the ablation cells on 2000 held-out scenarios each (the suite's 500 and
# 1500 more: ids 2^40 .. 2^40 + 1999 of root seed 0), on a lent machine's 16 CPU cores.
# Run from the repository root with ata.egg-info and .devcarry/site carried; an earlier call's
# output folders, carried back as .devcarry/r8eval/, are resumed (only missing units run).
# Usage: bash tools/round8/device_eval.sh SECONDS
export PYTHONPATH=$PWD:$PWD/.devcarry/site PYTHONUNBUFFERED=1
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
nproc; python3 -c 'import torch,numpy,sys;print(sys.version.split()[0],torch.__version__,numpy.__version__)'
mkdir -p /tmp/r8eval; [ -d .devcarry/r8eval ] && cp -r .devcarry/r8eval/* /tmp/r8eval/
t0=$(date +%s); left=$1
timeout $left python3 -c 'from ata.cli import app; app()' eval examples/paper_suite.toml \
  --methods "ATA-HRL,w/o.AUX,w/o.C" --levels high -n 2000 -w 16 -q -o /tmp/r8eval/high
echo "high: exit $? after $(( $(date +%s) - t0 )) s"
left=$(( $1 - ($(date +%s) - t0) ))
if [ $left -gt 30 ]; then
  timeout $left python3 -c 'from ata.cli import app; app()' eval examples/paper_suite.toml \
    --methods "ATA-HRL,w/o.C" --levels low,medium -n 2000 -w 16 -q -o /tmp/r8eval/lowmed
  echo "lowmed: exit $? after $(( $(date +%s) - t0 )) s"
fi
for d in /tmp/r8eval/*; do echo "$d: $(( $(wc -l < $d/units.jsonl) )) units of $(grep -o '"units": [0-9]*' $d/plan.json)"; done
cd /tmp && tar -czf $OUT/r8eval.tgz r8eval && ls -la $OUT

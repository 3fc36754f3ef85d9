# Issue 11, round 3, call 2: resume the 10 runs of .devcarry/round2 (lr 5e-4 and 2.5e-4) and start
# 5 more at lr 5e-4 from other seeds, in parallel, under timeout 520 s; every run folder comes back.
export PYTHONPATH=$PWD:$PWD/.devcarry/site PYTHONUNBUFFERED=1
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
mkdir -p /tmp/runs && cp -r .devcarry/round2/* /tmp/runs/; t0=$(date +%s)
old=($(ls .devcarry/round2)); new=()
for n in "${old[@]}"; do
  timeout 520 python3 -c 'from ata.cli import app; app()' train --resume /tmp/runs/$n > /tmp/runs/$n/train2.out 2>&1 &
done
for seed in 2024 55 808 1234 99; do
  name=a_lr5e-4_s$seed; new+=($name); mkdir -p /tmp/runs/$name
  timeout 520 python3 -c 'from ata.cli import app; app()' train --plugins ita \
    --set ata_hrl.init_from=.devcarry/ita_a_best.pt --set ata_hrl.ita_steps=1000 \
    --set ata_hrl.lr=5e-4 --set ata_hrl.seed=$seed --set ata_hrl.eval_every=20 \
    --set ata_hrl.eval_scenarios=128 --set ata_hrl.checkpoint_every=5 --set ata_hrl.threads=1 \
    -o /tmp/runs/$name > /tmp/runs/$name/train.out 2>&1 &
done
wait; echo "elapsed $(( $(date +%s) - t0 )) s"
cd /tmp/runs && rm -f */*.tmp; names=("${old[@]}" "${new[@]}")
{ for n in "${names[@]}"; do
    echo "== $n rows=$(( $(wc -l < $n/log.csv) - 1 ))"
    awk -F, 'NR>1 && $12!="" {printf "  %s,%s,%s\n",$2,$12,$13}' $n/log.csv; tail -1 $n/train*.out
  done; } > $OUT/summary2.txt
tar -cf $OUT/r2_p1.tar "${names[@]:0:5}"; tar -cf $OUT/r2_p2.tar "${names[@]:5:5}"; tar -cf $OUT/r2_p3.tar "${names[@]:10}"
ls -la $OUT; cat $OUT/summary2.txt

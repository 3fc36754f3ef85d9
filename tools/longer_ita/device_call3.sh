# Issue 11, round 3, call 3: 15 continuation runs of the (a) ITA (ITA_750) trained on the three
# uncertainty levels in turn (ata_hrl.uncertainty_levels), in parallel, under timeout 440 s.
export PYTHONPATH=$PWD:$PWD/.devcarry/site PYTHONUNBUFFERED=1
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
mkdir -p /tmp/runs; t0=$(date +%s); names=()
for cfg in 5e-4:12345 5e-4:777 5e-4:4242 5e-4:9001 5e-4:31337 5e-4:2024 5e-4:55 5e-4:808 \
           2.5e-4:12345 2.5e-4:777 2.5e-4:4242 2.5e-4:9001 2.5e-4:31337 2.5e-4:2024 2.5e-4:55; do
  lr=${cfg%%:*}; seed=${cfg#*:}; name=m_lr${lr}_s${seed}; names+=($name); mkdir -p /tmp/runs/$name
  timeout 440 python3 -c 'from ata.cli import app; app()' train --plugins ita \
    --set ata_hrl.init_from=.devcarry/ita_a_best.pt --set ata_hrl.ita_steps=1000 \
    --set "ata_hrl.uncertainty_levels=['low','medium','high']" \
    --set ata_hrl.lr=$lr --set ata_hrl.seed=$seed --set ata_hrl.eval_every=21 \
    --set ata_hrl.eval_scenarios=64 --set ata_hrl.checkpoint_every=3 --set ata_hrl.threads=1 \
    -o /tmp/runs/$name > /tmp/runs/$name/train.out 2>&1 &
done
wait; echo "elapsed $(( $(date +%s) - t0 )) s"
cd /tmp/runs && rm -f */*.tmp
{ for n in "${names[@]}"; do
    echo "== $n rows=$(( $(wc -l < $n/log.csv) - 1 ))"
    awk -F, 'NR>1 && $12!="" {printf "  %s,%s,%s\n",$2,$12,$13}' $n/log.csv; tail -n 2 $n/train.out
  done; } > $OUT/summary3.txt
tar -cf $OUT/r3_p1.tar "${names[@]:0:5}"; tar -cf $OUT/r3_p2.tar "${names[@]:5:5}"; tar -cf $OUT/r3_p3.tar "${names[@]:10}"
ls -la $OUT; cat $OUT/summary3.txt

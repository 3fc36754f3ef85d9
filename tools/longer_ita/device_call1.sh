# Issue 11, round 3, call 1: 15 continuation runs of the (a) ITA (runs/ita_a/best.pt, step 750),
# in parallel, one torch thread each, under timeout 530 s; every run folder comes back.
export PYTHONPATH=$PWD:$PWD/.devcarry/site PYTHONUNBUFFERED=1
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
nproc; python3 -c 'import torch,numpy,sys;print(sys.version.split()[0],torch.__version__,numpy.__version__)'
python3 -c 'from importlib.metadata import entry_points as e; print(len(e(group="ata.optional")))'
mkdir -p /tmp/runs; t0=$(date +%s)
names=()
for lr in 1e-3 5e-4 2.5e-4; do for seed in 12345 777 4242 9001 31337; do
  name=a_lr${lr}_s${seed}; names+=($name); mkdir -p /tmp/runs/$name
  timeout 530 python3 -c 'from ata.cli import app; app()' train --plugins ita \
    --set ata_hrl.init_from=.devcarry/ita_a_best.pt --set ata_hrl.ita_steps=1000 \
    --set ata_hrl.lr=$lr --set ata_hrl.seed=$seed --set ata_hrl.eval_every=20 \
    --set ata_hrl.eval_scenarios=128 --set ata_hrl.checkpoint_every=5 --set ata_hrl.threads=1 \
    -o /tmp/runs/$name > /tmp/runs/$name/train.out 2>&1 &
done; done
wait; echo "elapsed $(( $(date +%s) - t0 )) s"
cd /tmp/runs && rm -f */*.tmp
{ for n in "${names[@]}"; do
    echo "== $n rows=$(( $(wc -l < $n/log.csv) - 1 ))"
    awk -F, 'NR>1 && $12!="" {printf "  %s,%s,%s\n",$2,$12,$13}' $n/log.csv; tail -2 $n/train.out
  done; } > $OUT/summary1.txt
tar -cf $OUT/r1_p1.tar "${names[@]:0:5}"; tar -cf $OUT/r1_p2.tar "${names[@]:5:5}"; tar -cf $OUT/r1_p3.tar "${names[@]:10}"
ls -la $OUT; cat $OUT/summary1.txt

#!/bin/bash
# usage: ab_load.sh OUTDIR CODEDIR [env...]  -- one load run with the server from CODEDIR
out=$1; code=$2; shift 2
mkdir -p $out
db=$(mktemp -d /tmp/svccost/db.XXXX)
port=$((8700 + RANDOM % 200))
cd $code
env "$@" PYTHONPATH=$code nice -n 5 /work/main/.venv/bin/python -m cpkb serve --db sqlite:///$db/kb.sqlite --port $port > $out/server.log 2>&1 &
spid=$!
for i in $(seq 200); do curl -s -o /dev/null http://127.0.0.1:$port/healthz && break; sleep 0.5; done
cd /work/wt/svccost
PYTHONPATH=/work/wt/svccost nice -n 5 /work/main/.venv/bin/python benchmarks/load.py --url http://127.0.0.1:$port --planners 1 --writers 4 --seed-points 1000 --duration 30 --out $out > $out/load.txt 2>&1 &
lpid=$!
for i in $(seq 600); do grep -q "/suggest" $out/server.log && break; sleep 0.2; done
c0=$(for p in $spid $(pgrep -P $spid); do awk '{s+=$14+$15} END {print s}' /proc/$p/stat; done | paste -sd' ')
l0=$(cat /proc/loadavg | cut -d' ' -f1)
wait $lpid
c1=$(for p in $spid $(pgrep -P $spid); do awk '{s+=$14+$15} END {print s}' /proc/$p/stat; done | paste -sd' ')
l1=$(cat /proc/loadavg | cut -d' ' -f1)
kill $spid; wait $spid 2>/dev/null
rm -rf $db
python3 - "$out" "$c0" "$c1" "$l0" "$l1" <<'PY'
import json, sys, glob, numpy as np
out, c0, c1, l0, l1 = sys.argv[1:]
d = json.load(open(sorted(glob.glob(out + '/load-*.json'))[-1]))
s = [json.loads(l) for l in open(out + '/server.log') if l.startswith('{')]
sd = np.array([r['duration_ms'] for r in s if r.get('path', '').endswith('/suggest')])
e = d['endpoints']
print(f"suggest p50 {e['suggest']['p50_ms']:.1f} p95 {e['suggest']['p95_ms']:.1f} p99 {e['suggest']['p99_ms']:.1f} n {e['suggest']['requests']} | server-side p50 {np.percentile(sd,50):.1f} p95 {np.percentile(sd,95):.1f} | posts {e['post_points']['requests']} p95 {e['post_points']['p95_ms']:.1f} | ok {d['exactly_once']['ok']} | cpu_s server,child {c0} -> {c1} | load {l0} {l1}")
PY

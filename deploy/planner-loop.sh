#!/bin/sh
# A planner worker for docker-compose.yml: RUNS rounds of `cpkb plan` over TASKS on one shared
# knowledge base, so that every worker's failures become every other worker's knowledge.
# Usage: planner-loop.sh KB_URL KB TASKS(comma-separated) METHOD RUNS [MAX_ROLLOUTS]
# Seeds: each container takes its own block of 100000 seeds (from its host name), run i uses
# block + i; the seed is in every run's JSON line, so any run can be replayed with `cpkb plan`.
#
# An unsolved run (status 1) is a result, not an error: the loop goes on. Any other failure
# (the service restarting, a network fault) is retried after a pause; after RETRIES failures in
# a row the worker exits non-zero and compose's restart policy brings it back.
set -u
kb_url="$1"
kb="$2"
tasks="$3"
method="$4"
runs="$5"
max_rollouts="${6:-2000}"
retries="${CPKB_WORKER_RETRIES:-10}"
pause="${CPKB_WORKER_PAUSE_S:-5}"
block=$(( $(hostname | cksum | cut -d ' ' -f 1) % 20000 * 100000 ))
failures=0
i=0
while [ "$i" -lt "$runs" ]; do
    for task in $(echo "$tasks" | tr ',' ' '); do
        seed=$((block + i))
        while :; do
            cpkb plan --task "$task" --method "$method" --seed "$seed" --max-rollouts "$max_rollouts" --kb-url "$kb_url" --kb "$kb" --json --quiet
            status=$?
            if [ "$status" -le 1 ]; then
                failures=0
                break
            fi
            failures=$((failures + 1))
            echo "planner-loop: $task seed $seed failed with status $status ($failures in a row)" >&2
            if [ "$failures" -ge "$retries" ]; then
                exit "$status"
            fi
            sleep "$pause"
        done
    done
    i=$((i + 1))
done

#!/bin/sh
# A planner worker for docker-compose.yml: RUNS rounds of `cpkb plan` over TASKS on one shared
# knowledge base, so that every worker's failures become every other worker's knowledge.
# Usage: planner-loop.sh KB_URL KB TASKS(comma-separated) METHOD RUNS
# Seeds: each container takes its own block of 100000 seeds (from its host name), run i uses
# block + i; the seed is in every run's JSON line, so any run can be replayed with `cpkb plan`.
set -eu
kb_url="$1"
kb="$2"
tasks="$3"
method="$4"
runs="$5"
block=$(( $(hostname | cksum | cut -d ' ' -f 1) % 20000 * 100000 ))
i=0
while [ "$i" -lt "$runs" ]; do
    for task in $(echo "$tasks" | tr ',' ' '); do
        seed=$((block + i))
        cpkb plan --task "$task" --method "$method" --seed "$seed" --kb-url "$kb_url" --kb "$kb" --json --quiet
    done
    i=$((i + 1))
done

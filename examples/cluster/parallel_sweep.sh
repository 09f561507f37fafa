#!/bin/bash
# A lay-up sweep spread over several machines (or processes) with GNU parallel: shard I of N
# runs on whichever host parallel picks (--sshloginfile for remote hosts sharing the
# directory), then the shards are merged into the directory a single-machine sweep would have
# written (summary.csv byte for byte the same).
#
#   bash examples/cluster/parallel_sweep.sh [N]      # N shards, default 4
set -euo pipefail
n="${1:-4}"
mkdir -p sweep
seq 1 "$n" | parallel --halt now,fail=1 \
    flexsens sweep decks/slider_crank_beam.toml \
        --vary design.theta=-90:5:90 \
        --shard "{}/$n" -j 1 -o "sweep/shard_{}" --quiet
flexsens merge $(seq -f "sweep/shard_%g" 1 "$n") -o sweep/all

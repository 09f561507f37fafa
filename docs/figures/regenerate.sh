#!/bin/sh
# Regenerate the figures of docs/paper-reproduction.md from scratch (about 1.5 min on 2 cores):
#   sh docs/figures/regenerate.sh
# Runs `flexsens report` on the paper's two decks and copies the figures the document shows.
set -eu
cd "$(dirname "$0")/../.."
out=$(mktemp -d)
cargo run --release -q -p flexsens -- report decks/slider_crank_beam.toml --layups 0,15,30 -o "$out/beam" --quiet
cargo run --release -q -p flexsens -- report decks/slider_crank_plate.toml --layups 0,15,30,75 -o "$out/plate" --quiet
for f in displacement integrators_15deg integrators_30deg modes_15deg perturbations_15deg; do
  cp "$out/beam/$f.png" "docs/figures/beam_$f.png"
done
for f in displacement modes_0deg perturbations_15deg perturbations_30deg perturbations_75deg; do
  cp "$out/plate/$f.png" "docs/figures/plate_$f.png"
done
cp "$out/beam/summary.md" docs/figures/beam_summary.md
cp "$out/plate/summary.md" docs/figures/plate_summary.md
echo "figures and summaries copied to docs/figures (all files of the reports: $out)"

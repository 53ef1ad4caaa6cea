#!/usr/bin/env bash
# A fuzzing campaign as README.md ("Fuzzing") reports them: WORKERS processes
# of one target's `--sanitizer none -O` build share one corpus, started from
# fuzz/corpus/TARGET, each stopping after RUNS executions; the total is the
# sum of their stat::number_of_executed_units. Workers run at nice 10, so a
# build or CI on the same cores goes first.
#
#   fuzz/campaign.sh TARGET WORKERS RUNS DIR [libFuzzer flags...]
#   fuzz/campaign.sh api_sequence 2 5000000 /work/fuzzrun/run -max_len=256 -entropic=0
#
# Comparison tracing helps only where raw input bytes meet magic values
# (decode_block, open_and_query). The other targets' input only chooses
# operations, or fields and values that the forger seals: there it halves
# the rate and adds no reach (forge_lod, 180 s each from fuzz/corpus:
# 287,066 runs to cov 4681 ft 15527 with it; 514,338 to cov 4740 ft 16742
# without, and cov 4677 ft 15404 at its 289,950th). Those are built with
# --no-trace-compares.
set -euo pipefail
[ $# -ge 4 ] || { echo "usage: $0 TARGET WORKERS RUNS DIR [libFuzzer flags...]" >&2; exit 2; }
target=$1 workers=$2 runs=$3 dir=$4
shift 4
cd "$(dirname "$0")"
trace=()
case $target in decode_block | open_and_query) ;; *) trace=(--no-trace-compares) ;; esac
cargo fuzz build --sanitizer none -O "${trace[@]}" "$target"
mkdir -p "$dir/corpus" "$dir/artifacts"
cp -rn "corpus/$target/." "$dir/corpus/"
binary="$dir/$target.$(git rev-parse --short HEAD)"
cp "target/x86_64-unknown-linux-gnu/release/$target" "$binary"
for w in $(seq 1 "$workers"); do
  nice -n 10 "$binary" "$dir/corpus" -runs="$runs" -timeout=60 -print_final_stats=1 \
    -artifact_prefix="$dir/artifacts/" "$@" > "$dir/w$w.log" 2>&1 &
done
wait
total=$(grep -h '^stat::number_of_executed_units' "$dir"/w*.log | awk '{s += $2} END {print s}')
echo "$target: $total executions over $workers workers ($binary); artifacts: $(ls "$dir/artifacts" | wc -l)"

#!/usr/bin/env bash
# Throughput A/B of the step against an earlier commit: alternating processes of
# `benchmarks/throughput.py --breakdown BATCH` on REV (a git worktree) and on this checkout.
#   bash benchmarks/ab_breakdown.sh REV [ROUNDS] [BATCH]
# Compare "full step" with "mjx.step alone" (the control) within each run: the machine is
# shared, so absolute figures drift between runs.
set -euo pipefail
rev="${1:?usage: ab_breakdown.sh REV [ROUNDS] [BATCH]}"; rounds="${2:-2}"; batch="${3:-512}"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
py="${JAXGAIT_PYTHON:-$here/.venv/bin/python}"
old="$(mktemp -d)/old"
git -C "$here" worktree add -f "$old" "$rev" -q
trap 'git -C "$here" worktree remove --force "$old"' EXIT
for r in $(seq "$rounds"); do
  for side in old new; do
    dir="$here"; [ "$side" = old ] && dir="$old"
    echo "=== $side ($( git -C "$dir" rev-parse --short HEAD)) round $r $(date +%T)"
    (cd "$dir" && PYTHONPATH="$dir" JAXGAIT_CACHE_DIR="$dir/.jax_cache" "$py" \
      benchmarks/throughput.py --breakdown "$batch" --steps 200 --repeats 7)
  done
done

#!/usr/bin/env bash
# Explicit MPC at scale: the measurements behind BENCHMARKS.md "Explicit MPC
# at scale" and docs/empc.md (not part of CI: about 10 minutes on 2 cores,
# most of it the N = 10 problem; PPOPT adds about an hour when asked for).
#
#   bash scripts/empc-scale.sh [OUT_DIR]          # kestrel only
#   EMPC_PPOPT=1 bash scripts/empc-scale.sh       # also PPOPT (pip install ppopt daqp cvxopt)
#
# Problems: kestrel_empc::testing::scaled_thesis (random 5-state, 4-input
# systems, 9 parameters; seeds chosen for the issue's region counts) and the
# tricopter's N = 10, blocks [1, 1, 2, 6] problem from `kestrel mpc`.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/empc-scale}
mkdir -p "$out"
cargo build --release -p kestrel-tools
cargo build --release -p kestrel-empc --features parallel \
    --example scale_problems --example mpqp_scale --example locate_file
bin=target/release
ex=target/release/examples

# name seed N Ns: 75, 1,075, 1,395 and 8,611 regions.
while read -r name seed n ns; do
    "$ex/scale_problems" write "$seed" "$n" "$ns" "$out/$name.mpqp.json"
done <<'LIST'
random-n2-b2-75 1 2 1
random-n5-b14-1075 401 5 2
random-n3-b12-1395 1284 3 2
random-n4-b112-8611 32 4 3
LIST
"$bin/kestrel" mpc --model models/tricopter-blackbox-5.json --horizon 10 --blocks 1,1,2,6 \
    --q1 2000 --q2 0.01 --out "$out/tricopter-n10-b1126.mpqp.json" --force 2>/dev/null

for p in random-n2-b2-75 random-n5-b14-1075 random-n3-b12-1395 random-n4-b112-8611 tricopter-n10-b1126; do
    f="$out/$p.mpqp.json"
    echo "== $p"
    # The mpQP alone: counters, time per region, a hash of the regions.
    "$ex/mpqp_scale" "$f" parallel
    # kestrel empc solve end to end (solve + point location of the first
    # move, --locate auto), wall and CPU time.
    /usr/bin/time -f "kestrel empc solve --first-move 4: %e s wall, %U s user, %M kB" \
        "$bin/kestrel" empc solve --problem "$f" --first-move 4 --no-regions --out "$out/$p.empc.json" --force
    # The candidate lists: exactness at 10^4 random parameters against the
    # region lookup, evaluation time, size, worst case (H4's example).
    case $p in
        tricopter*) "$ex/locate_file" "$f" 4 2000 64 0.85 2 ;;
        *) "$ex/locate_file" "$f" 4 10000 ;;
    esac
    if [ "${EMPC_PPOPT:-0}" = 1 ] && [ "$p" != tricopter-n10-b1126 ]; then
        python3 scripts/empc-ppopt.py "$f" combinatorial_graph combinatorial_parallel graph
    fi
done

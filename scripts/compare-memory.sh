#!/usr/bin/env bash
# Peak resident set size of hemi and of native Embree 3 (../shared/peers/native) rendering the
# same peer scenes, as `/usr/bin/time -v` reports it ("Maximum resident set size"): one render
# each per round, the two alternating, at the scene's own size; prints the medians over the
# rounds as a Markdown table with hemi ÷ Embree, and the machine and commands.
#
#   scripts/compare-memory.sh [--spp N] [--threads N] [--rounds N] [--hemi BIN] [SCENE ...]
#
# Defaults: 1 spp, 2 threads, 3 rounds, target/release/hemi, and all five peer scenes. The
# native bench is built on first use (scripts/native-embree.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
peers_src="$root/../shared/peers"
spp=1
threads=2
rounds=3
hemi="$root/target/release/hemi"
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        --hemi) hemi="$2"; shift 2 ;;
        -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
        *) scenes+=("$1"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || scenes=(dragon many_spheres sponza sphere_plane cornell)
for n in "$spp" "$threads" "$rounds"; do
    [[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "compare-memory: '$n' is not a positive whole number" >&2; exit 2; }
done
[ -x "$hemi" ] || { echo "compare-memory: $hemi not found (cargo build --release first)" >&2; exit 1; }

. "$root/scripts/native-embree.sh"
[ -x /usr/bin/time ] || native_apt time

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# Maximum resident set size, in KiB, of the command after `--`.
peak_kib() {
    /usr/bin/time -v -o "$tmp/time" "$@" >/dev/null 2>"$tmp/err" || { cat "$tmp/err" >&2; exit 1; }
    awk -F': ' '/Maximum resident set size/ {print $2}' "$tmp/time"
}
declare -A hemi_kib native_kib
for s in "${scenes[@]}"; do
    [ -f "$peers_src/scenes/$s.json" ] || { echo "compare-memory: no scene $s in $peers_src/scenes" >&2; exit 2; }
    native_scene "$s" >/dev/null
done
for round in $(seq "$rounds"); do
    for s in "${scenes[@]}"; do
        # Alternate which runs first, so a slow or crowded spell hits both alike.
        if [ $((round % 2)) = 1 ]; then
            h=$(peak_kib "$hemi" render "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" --out "$tmp/$s.exr")
            n=$(peak_kib "$native_bench" "$native/out/$s.aoscene" --spp "$spp" --repeat 1 --threads "$threads")
        else
            n=$(peak_kib "$native_bench" "$native/out/$s.aoscene" --spp "$spp" --repeat 1 --threads "$threads")
            h=$(peak_kib "$hemi" render "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" --out "$tmp/$s.exr")
        fi
        hemi_kib[$s]="${hemi_kib[$s]:-} $h"
        native_kib[$s]="${native_kib[$s]:-} $n"
        echo "round $round $s: hemi $h KiB, native Embree $n KiB" >&2
    done
done

median() { tr ' ' '\n' | grep . | sort -n | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }
echo "| scene (triangles) | hemi peak RSS (MiB) | native Embree 3 (MiB) | hemi ÷ Embree |"
echo "|---|---|---|---|"
for s in "${scenes[@]}"; do
    tris=$(native_triangles "$native/out/$s.aoscene")
    h=$(echo "${hemi_kib[$s]}" | median)
    n=$(echo "${native_kib[$s]}" | median)
    awk -v s="$s" -v t="$tris" -v h="$h" -v n="$n" \
        'BEGIN {printf "| %s (%d) | %.1f | %.1f | %.2f |\n", s, t, h / 1024, n / 1024, h / n}'
done
echo
echo "Medians of $rounds rounds; $(lscpu | awk -F': +' '/^Model name/ {print $2}'), $(nproc) CPUs;" \
    "hemi $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo '?'):" \
    "\`hemi render SCENE.json --spp $spp --threads $threads --out OUT.exr\`," \
    "\`embree_ao_bench_e3 SCENE.aoscene --spp $spp --repeat 1 --threads $threads\`."

#!/usr/bin/env bash
# The quality of hemi's BVH against native Embree 3's on the same peer scenes, by the surface
# area heuristic as Embree's own statistics compute it: each inner node's box and each leaf's
# box times its primitive blocks (Embree's Triangle4, hemi's packets of four), as half areas
# over the root box's. hemi's figure is `--stats-json`'s `bvh.largest_blas`; Embree's is what
# a copy of ../shared/peers/native's bench prints with the device option `verbose=3` (built
# once in $HEMI_NATIVE_DIR/verbose, default /tmp/hemi-native/verbose), at its default build
# quality (medium, what the speed comparisons run) and at high (spatial splits). A scene whose
# shared meshes hemi stores once and instances under the peer contract (many_spheres) is read
# from its glTF file instead, jittered, at a size and spp that make hemi bake them into one
# tree (docs/design.md, "Baking"), so both sides describe one tree over every triangle.
#
#   scripts/compare-trees.sh [BINARY] [SCENE ...]
#
# Defaults: target/release/hemi and all five peer scenes. Prints a Markdown table.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
peers_src="$root/../shared/peers"
hemi="$root/target/release/hemi"
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
        */*|hemi) hemi="$1"; shift ;;
        *) scenes+=("$1"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || scenes=(sphere_plane cornell many_spheres dragon sponza)
[ -x "$hemi" ] || { echo "compare-trees: $hemi not found (cargo build --release first)" >&2; exit 1; }

. "$root/scripts/native-embree.sh"
verbose_build="$native/verbose"
verbose_bench="$verbose_build/build/embree_ao_bench_e3"
if [ ! -x "$verbose_bench" ]; then
    echo "compare-trees: building a copy of the native bench whose --verbose prints Embree's BVH statistics" >&2
    rm -rf "$verbose_build" && mkdir -p "$verbose_build"
    cp "$peers_src/native/embree_ao_bench.cpp" "$peers_src/native/Makefile" "$verbose_build/"
    chmod -R u+w "$verbose_build"
    sed -i 's/cfg += ",verbose=1"/cfg += ",verbose=3"/' "$verbose_build/embree_ao_bench.cpp"
    grep -q 'cfg += ",verbose=3"' "$verbose_build/embree_ao_bench.cpp" ||
        { echo "compare-trees: could not set the bench's verbosity" >&2; exit 1; }
    make -s -C "$verbose_build" >&2
fi

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# hemi's statistics of rendering ARGS into $tmp/stats.json.
hemi_stats() {
    "$hemi" render "$@" --out "$tmp/image.exr" --stats-json "$tmp/stats.json" >/dev/null 2>"$tmp/err" ||
        { cat "$tmp/err" >&2; exit 1; }
}
echo "| scene | triangles | hemi SAH (inner + leaves) | Embree 3, medium | hemi ÷ Embree | Embree 3, high | hemi ÷ Embree |"
echo "|---|---|---|---|---|---|---|"
for s in "${scenes[@]}"; do
    [ -f "$peers_src/scenes/$s.json" ] || { echo "compare-trees: no scene $s in $peers_src/scenes" >&2; exit 2; }
    scene="$(native_scene "$s")"
    tris=$(native_triangles "$scene")
    for quality in medium high; do
        "$verbose_bench" "$scene" --spp 1 --repeat 1 --quality "$quality" --verbose >"$tmp/embree_$quality" 2>&1
    done
    hemi_stats "$peers_src/scenes/$s.json" --spp 1
    stored=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["frames"][0]["bvh"]["triangles"])' "$tmp/stats.json")
    if [ $((10 * stored)) -lt $((9 * tris)) ]; then
        # Shared meshes stored once and instanced: the glTF file, jittered, with max_spp × pixels
        # at 64 camera rays per placed triangle, which bakes them.
        mesh=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["mesh"])' "$peers_src/scenes/$s.json")
        hemi_stats "$peers_src/scenes/$mesh" --size 1024x1024 --spp $(((64 * tris + 1048575) / 1048576))
    fi
    python3 - "$s" "$tris" "$tmp/stats.json" "$tmp/embree_medium" "$tmp/embree_high" <<'PY'
import json, re, sys
scene, tris, stats, medium, high = sys.argv[1:]
blas = json.load(open(stats))["frames"][0]["bvh"]["largest_blas"]

def embree(path):
    text = open(path).read()
    found = re.search(r"^\s*total\s*:\s*sah\s*=\s*([0-9.]+)", text, re.M)
    if not found:
        sys.exit(f"compare-trees: no BVH statistics in the native bench's output ({path})")
    return float(found.group(1))

m, h = embree(medium), embree(high)
print(f"| {scene} | {int(tris):,} | {blas['sah']:.3f} ({blas['sah_inner']:.3f} + {blas['sah_leaves']:.3f}) "
      f"| {m:.3f} | {blas['sah'] / m:.3f} | {h:.3f} | {blas['sah'] / h:.3f} |")
PY
done
echo
echo "$(lscpu | awk -F': +' '/^Model name/ {print $2}'); hemi $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo '?')," \
    "Embree $(grep -o '"embree": "[^"]*"' "$tmp/embree_medium" | cut -d'"' -f4)."

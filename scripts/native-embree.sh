# Sourced by the scripts that measure hemi against native Embree, with $peers_src set and the
# peers' venv made in $work (scripts/peers-venv.sh: numpy, and the copy of the peers whose
# peerlib the scene export imports): builds the native bench in $work/native on first use, installing g++ and Debian's
# Embree 3 with apt-get when missing and run as root, and defines
#   native_scene NAME   -> prints the path of NAME's exported .aoscene (exported once)
#   native_best NAME SPP THREADS [ARGS...] -> runs the bench in --stream, --packet 8 and
#                          --packet 16 and prints the JSON line of the mode with the best ao_mrays_s
native="$work/native"
if [ ! -x "$native/build/embree_ao_bench_e3" ]; then
    if [ ! -e /usr/include/embree3/rtcore.h ] || ! command -v g++ >/dev/null; then
        [ "$(id -u)" = 0 ] || { echo "$(basename "$0" .sh): native Embree needs g++ and libembree-dev (apt-get install -y g++ libembree-dev)" >&2; exit 1; }
        apt-get install -y -q g++ libembree-dev >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q g++ libembree-dev >/dev/null; }
    fi
    echo "$(basename "$0" .sh): building the native Embree bench in $native" >&2
    make -s -C "$native" >&2
fi
native_scene() {
    local scene="$native/out/$1.aoscene"
    if [ ! -s "$scene" ]; then
        mkdir -p "$native/out"
        (cd "$native" && "$work/.venv/bin/python" export_scene.py "$peers_src/scenes/$1.json" -o "$scene" >&2)
    fi
    echo "$scene"
}
native_best() {
    local name="$1" spp="$2" threads="$3"
    shift 3
    local scene
    scene="$(native_scene "$name")"
    for mode in "--stream" "--packet 8" "--packet 16"; do
        # shellcheck disable=SC2086
        "$native/build/embree_ao_bench_e3" "$scene" --spp "$spp" --threads "$threads" $mode "$@" 2>/dev/null | tail -1
    done | python3 -c "import json,sys; runs=[json.loads(l) for l in sys.stdin if l.strip()]; print(json.dumps(max(runs, key=lambda d: d['ao_mrays_s'])))"
}

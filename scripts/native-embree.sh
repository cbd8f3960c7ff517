# Sourced by the scripts that measure hemi against native Embree, with $peers_src set: builds
# ../shared/peers/native's bench on first use in $native (HEMI_NATIVE_DIR, default
# /tmp/hemi-native) from a copy, as its README says (g++ and Debian's libembree-dev, and numpy
# for its scene export, installed with apt-get when missing and run as root), and defines
#   native_scene NAME [WIDTH HEIGHT] -> prints the path of peer scene NAME's .aoscene, at its
#                          own size or the one given (exported once)
#   native_triangles FILE -> prints the triangle count in an .aoscene file's header
#   native_best NAME SPP THREADS [ARGS...] -> runs the bench in --stream, --packet 8 and
#                          --packet 16 and prints the JSON line of the mode with the best ao_mrays_s
# With HEMI_NO_AVX512=1, as hemi then runs its AVX2 kernels, the bench is an AVX2 one: its copy
# (in $native/avx2) opens its Embree device with "isa=avx2" and is compiled without AVX-512, so
# both sides of a ratio run eight-lane code on the same CPU.
native="${HEMI_NATIVE_DIR:-/tmp/hemi-native}"
native_build="$native"
native_isa=""
if [ "${HEMI_NO_AVX512:-}" = 1 ]; then
    native_build="$native/avx2"
    native_isa="avx2"
fi
native_bench="$native_build/build/embree_ao_bench_e3"
native_apt() {
    [ "$(id -u)" = 0 ] || { echo "$(basename "$0" .sh): needs $* (apt-get install -y $*)" >&2; exit 1; }
    apt-get install -y -q "$@" >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q "$@" >/dev/null; }
}
[ -d "$peers_src/native" ] || { echo "$(basename "$0" .sh): $peers_src/native not found (../shared must sit beside the repo)" >&2; exit 1; }
if [ ! -x "$native_bench" ]; then
    echo "$(basename "$0" .sh): building the native Embree bench in $native_build" >&2
    command -v g++ >/dev/null && [ -e /usr/include/embree3/rtcore.h ] || native_apt g++ libembree-dev
    rm -rf "$native_build/build" && mkdir -p "$native_build"
    cp -r "$peers_src/native/." "$native_build/" && chmod -R u+w "$native_build"
    if [ -n "$native_isa" ]; then
        # The copy's device asks Embree for the ISA, and its Makefile's flags end in one that
        # leaves AVX-512 out of the bench's own code.
        sed -i 's/std::string cfg = "threads="/std::string cfg = "isa='"$native_isa"',threads="/' "$native_build/embree_ao_bench.cpp"
        sed -i 's/^\(CXXFLAGS ?= .*\)$/\1 -mno-avx512f/' "$native_build/Makefile"
        grep -q 'cfg = "isa='"$native_isa"',' "$native_build/embree_ao_bench.cpp" &&
            grep -q '^CXXFLAGS ?= .* -mno-avx512f$' "$native_build/Makefile" ||
            { echo "$(basename "$0" .sh): could not set the bench's ISA" >&2; exit 1; }
    fi
    make -s -C "$native_build" >&2
fi
native_python=python3
"$native_python" -c 'import numpy' 2>/dev/null || native_python=/usr/bin/python3
"$native_python" -c 'import numpy' 2>/dev/null || { native_apt python3-numpy; native_python=/usr/bin/python3; }
native_scene() {
    local scene="$native/out/$1${2:+_$2x$3}.aoscene"
    if [ ! -s "$scene" ]; then
        mkdir -p "$native/out"
        (cd "$native_build" && PYTHONPATH="$peers_src" "$native_python" export_scene.py "$peers_src/scenes/$1.json" \
            ${2:+--width "$2" --height "$3"} -o "$scene" >/dev/null)
    fi
    echo "$scene"
}
native_triangles() {
    od -An -t u4 -j 16 -N 4 "$1" | tr -d ' '
}
native_best() {
    local name="$1" spp="$2" threads="$3"
    shift 3
    local scene
    scene="$(native_scene "$name")"
    for mode in "--stream" "--packet 8" "--packet 16"; do
        # shellcheck disable=SC2086
        "$native_bench" "$scene" --spp "$spp" --threads "$threads" $mode "$@" 2>/dev/null | tail -1
    done | python3 -c "import json,sys; runs=[json.loads(l) for l in sys.stdin if l.strip()]; print(json.dumps(max(runs, key=lambda d: d['ao_mrays_s'])))"
}

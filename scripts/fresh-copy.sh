# Sourced by the timing scripts: `fresh_copy BINARY DIR` copies BINARY into DIR and prints the
# copy's path, so that every build is timed from a file in the same state. Straight after a
# build the binary's pages are the ones the linker wrote into the page cache, and some paths
# then run up to 8 % slower than the same bytes read afresh: ZSobol on cornell took 220 against
# 203 ms (trace stage, one thread) from target/release/hemi and from a copy of it, and the file
# itself ran as fast as the copy once the page cache was dropped.
fresh_copy() {
    local copy
    copy="$2/$(basename "$1")"
    cp "$1" "$copy"
    echo "$copy"
}

#!/usr/bin/env bash
# Seeds the corpus from the shared assets (not committed): fuzz/corpus/loaders/.
# Each seed is one byte (0: glTF/GLB, 1: peer scene) followed by the file.
set -e
cd "$(dirname "$0")"
A=../../shared/assets
out=corpus/loaders
mkdir -p "$out"
for f in Box/glTF-Embedded/Box.gltf Box/glTF-Binary/Box.glb BoxAnimated/glTF-Binary/BoxAnimated.glb \
    SimpleSparseAccessor/glTF-Embedded/SimpleSparseAccessor.gltf Cameras/glTF-Embedded/Cameras.gltf \
    AnimatedTriangle/glTF-Embedded/AnimatedTriangle.gltf SimpleInstancing/glTF-Binary/SimpleInstancing.glb \
    NegativeScaleTest/glTF-Binary/NegativeScaleTest.glb SimpleSkin/glTF/SimpleSkin.gltf \
    TriangleWithoutIndices/glTF/TriangleWithoutIndices.gltf; do
  { printf '\x00'; cat "$A/$f"; } > "$out/$(basename "$f")"
done
for f in ../../shared/peers/scenes/*.json; do
  { printf '\x01'; cat "$f"; } > "$out/$(basename "$f")"
done
ls "$out" | wc -l

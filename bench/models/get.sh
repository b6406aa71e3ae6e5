#!/usr/bin/env sh
# Fetches the four public models that `cargo bench --bench import_fit -- peers` reconstructs,
# from Alec Jacobson's common-3d-test-models (https://github.com/alecjacobson/common-3d-test-models):
#   stanford-bunny.obj  the scanned figure, open at its base (Stanford 3D Scanning Repository)
#   fandisk.obj         a CAD part with sharp edges (Hoppe)
#   rocker-arm.obj      a genus-1 mechanical part (INRIA)
#   spot.obj            a closed genus-0 character (Keenan Crane)
# The models are not committed here: the repository states no licence for them, each comes
# from its own source (see the repository's README).
#
#   bench/models/get.sh [DEST] [MIRROR]
#
# DEST defaults to this folder (the bench reads DYNACLAY_MODELS, default bench/models/).
# MIRROR, when given, is a local clone of the repository (a work tree, or a bare git dir read
# with `git show`); otherwise the files are downloaded from its raw GitHub URLs (curl or wget).
set -eu
here="$(cd "$(dirname "$0")" && pwd)"
dest="${1:-$here}"
mirror="${2:-}"
url="https://raw.githubusercontent.com/alecjacobson/common-3d-test-models/master/data"
mkdir -p "$dest"
for name in stanford-bunny fandisk rocker-arm spot; do
    out="$dest/$name.obj"
    if [ -s "$out" ]; then
        echo "have $out"
        continue
    fi
    if [ -n "$mirror" ] && [ -f "$mirror/data/$name.obj" ]; then
        cp "$mirror/data/$name.obj" "$out.part"
    elif [ -n "$mirror" ] && git -C "$mirror" cat-file -e "HEAD:data/$name.obj" 2>/dev/null; then
        git -C "$mirror" show "HEAD:data/$name.obj" > "$out.part"
    elif command -v curl >/dev/null 2>&1; then
        curl -fsSL "$url/$name.obj" -o "$out.part"
    elif command -v wget >/dev/null 2>&1; then
        wget -q "$url/$name.obj" -O "$out.part"
    else
        echo "no mirror given and neither curl nor wget found: cannot fetch $name.obj" >&2
        exit 1
    fi
    mv "$out.part" "$out"
    echo "wrote $out"
done

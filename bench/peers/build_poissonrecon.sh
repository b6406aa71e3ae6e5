#!/usr/bin/env sh
# Builds Kazhdan's PoissonRecon (screened Poisson surface reconstruction) from its source with
# its own Makefile, for bench/import_fit.rs (`-- peers`).
#
#   bench/peers/build_poissonrecon.sh <PoissonRecon source dir>
#
# The source is https://github.com/mkazhdan/PoissonRecon (a clone or an archive of it). The
# binary lands in <source dir>/Bin/Linux/PoissonRecon; the bench finds it through the
# POISSON_RECON environment variable, e.g.
#   POISSON_RECON=<source dir>/Bin/Linux/PoissonRecon cargo bench --bench import_fit -- peers
set -eu
src="${1:?usage: $0 <PoissonRecon source dir>}"
if [ ! -f "$src/Makefile" ] || [ ! -d "$src/Src" ]; then
    echo "$src does not look like a PoissonRecon source tree (no Makefile or Src/)" >&2
    exit 1
fi
jobs="${JOBS:-$(nproc 2>/dev/null || echo 1)}"
# The `poissonrecon` target builds the PoissonRecon binary alone, with the release flags of
# the Makefile (-O3 -DRELEASE -funroll-loops -ffast-math).
make -C "$src" -j"$jobs" poissonrecon
bin="$src/Bin/Linux/PoissonRecon"
if [ ! -x "$bin" ]; then
    echo "the build finished but $bin is missing" >&2
    exit 1
fi
echo "built $bin"
echo "run the bench with: POISSON_RECON=$bin cargo bench --bench import_fit -- peers"

"""The noise `dynaclay import` logs for clouds sampled by sample_cloud.py, against the noise they
were sampled with: per cloud, the log's figures (the noise read off quadrics where the cloud is
sparse, and the neighbours' planes' scatter) divided by the true sigma, both as a share of the
cloud's box's longest side; then the range and median of each over the clouds.

Usage: python3 bench/models/noise_reading.py DYNACLAY MODELS_DIR NOISE CLOUD.xyz...
(NOISE as given to sample_cloud.py: sigma = NOISE x the model's box diagonal; each cloud's
model is MODELS_DIR/<its file name up to the first -<digits>>.obj, e.g. rocker-arm-1000-3.xyz
is of rocker-arm.obj, as get.sh names them; needs numpy)

A cloud whose log gives no reading off quadrics (its screening radius was not widened) is
listed by name and left out of the ranges.
"""
import os
import re
import statistics
import subprocess
import sys
import tempfile

import numpy as np

if len(sys.argv) < 5:
    sys.exit(__doc__)
binary, models, noise_frac, clouds = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4:]
diagonals = {}


def true_sigma(cloud):
    """NOISE x the box diagonal of the cloud's model."""
    name = re.sub(r'-[0-9]+-.*', '', os.path.basename(cloud))
    if name not in diagonals:
        path = os.path.join(models, name + '.obj')
        vertices = np.array([list(map(float, line.split()[1:4]))
                             for line in open(path) if line.startswith('v ')])
        diagonals[name] = np.linalg.norm(vertices.max(0) - vertices.min(0))
    return noise_frac * diagonals[name]


READING = re.compile(r"noise ([\d.]+)% of the size \(estimated off quadrics; "
                     r"[^,]*, ([\d.]+)%")
quadrics, planes, without = [], [], []
# The sessions the imports write go to a folder of their own, removed at the end: nothing
# outside it is written or replaced.
with tempfile.TemporaryDirectory(prefix='noise_reading_') as scratch:
    session = os.path.join(scratch, 'reading.dclay')
    for cloud in clouds:
        run = subprocess.run([binary, 'import', cloud, '--out', session],
                             capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"{cloud}: dynaclay import failed:\n{run.stderr}")
        found = READING.search(run.stdout + run.stderr)
        if not found:
            without.append(cloud)
            continue
        points = np.loadtxt(cloud, usecols=(0, 1, 2))
        true_percent = 100 * true_sigma(cloud) / (points.max(0) - points.min(0)).max()
        quadrics.append(float(found.group(1)) / true_percent)
        planes.append(float(found.group(2)) / true_percent)
        print(f"{cloud} quadrics {quadrics[-1]:.2f} planes {planes[-1]:.2f}")
if quadrics:
    for name, ratios in (('quadrics', quadrics), ('planes', planes)):
        print(f"{name}: {len(ratios)} clouds, {min(ratios):.2f}-{max(ratios):.2f} times the "
              f"true noise, median {statistics.median(ratios):.2f}")
for cloud in without:
    print(f"{cloud}: no reading off quadrics")

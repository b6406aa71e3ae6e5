"""Reading and writing the `x y z nx ny nz` clouds that sample_cloud.py writes, for the helpers
beside it (one_view.py, sparse_side.py)."""
import os
import sys


def points(src):
    """Each point of SRC as (its six fields as text, their values), comments and blank lines
    passed over; a malformed line ends the script with the file, line and why."""
    with open(src) as cloud:
        for number, line in enumerate(cloud, 1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            if len(fields) != 6:
                sys.exit(f"{src}:{number}: expected x y z nx ny nz, found {len(fields)} fields")
            try:
                values = [float(v) for v in fields]
            except ValueError:
                sys.exit(f"{src}:{number}: a field is not a number")
            yield fields, values


def check_output(script, out, src):
    """Ends the script unless OUT is an .xyz path that is neither SRC nor a link."""
    if not out.endswith(".xyz"):
        sys.exit(f"{script}: OUT {out!r} must end in .xyz (the only kind this writes)")
    if os.path.exists(out) and (os.path.samefile(out, src) or os.path.islink(out)):
        sys.exit(f"{script}: OUT {out!r} is the input cloud or a link; choose another path")

#!/usr/bin/python3
"""Compares two HDF5 records dataset by dataset, bit for bit, and lists what differs.

For refactors that must not change results: run the same short job with the old and the new
build and compare the records (the master's, the DEM service's, dem_run's: any HDF5 file).

    /usr/bin/python3 scripts/compare_h5.py BEFORE.h5 AFTER.h5 [--exclude REGEX ...] [--quiet]

Every dataset of either file is compared: its shape, its type and every element's bits (NaN
equals NaN only with the same bits; 0.0 and -0.0 differ). Attributes of datasets and groups
are compared too. Datasets whose path matches an --exclude regular expression are only listed
as skipped (by default what differs between any two runs of the same code: wall-clock times,
`timing/` and `seconds_*`, and the bus counters under `bus/`, resends and round trips that
depend on the host's load). Exit code 0 when everything compared is
identical, 1 when anything differs or exists on one side only, 2 for a bad command line or an
unreadable file.
"""
import argparse
import re
import sys

import h5py
import numpy as np

# Differs between any two runs, same code or not: wall-clock times and the bus counters.
DEFAULT_EXCLUDE = [r"(^|/)timing(/|$)", r"(^|/)seconds_", r"(^|/)wall_", r"(^|/)bus(/|$)"]


def walk(f):
    """{path: object} for every group and dataset below the root (the root is '/')."""
    items = {"/": f}
    f.visititems(lambda name, obj: items.__setitem__("/" + name, obj))
    return items


def same_array(a, b):
    """(identical, note) for two numpy arrays, bit for bit."""
    if a.shape != b.shape:
        return False, f"shape {a.shape} != {b.shape}"
    if a.dtype != b.dtype:
        return False, f"type {a.dtype} != {b.dtype}"
    if a.dtype.kind in "fc":
        ab, bb = np.ascontiguousarray(a).view(np.uint8), np.ascontiguousarray(b).view(np.uint8)
        if np.array_equal(ab, bb):
            return True, ""
        bad = a != b
        bad |= np.isnan(a) != np.isnan(b)
        # elements whose bits differ though they compare equal (0.0 and -0.0, NaN payloads)
        n = int(np.count_nonzero(bad)) if bad.shape else int(bool(bad))
        if a.size and a.shape:
            idx = np.argwhere(bad)
            first = tuple(int(i) for i in idx[0]) if len(idx) else None
            diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
            finite = diff[np.isfinite(diff)]
            worst = float(finite.max()) if finite.size else float("nan")
            return False, (f"{n} of {a.size} elements differ (first at {first}, largest difference "
                           f"{worst:.3g})" if n else "bits differ (0.0 against -0.0 or NaN payloads)")
        return False, f"{a[()]!r} != {b[()]!r}"
    if a.dtype.kind == "V" or a.dtype.names:  # compound: compare the raw bytes
        same = a.tobytes() == b.tobytes()
        return same, "" if same else "compound values differ"
    same = np.array_equal(a, b)
    return same, "" if same else "values differ"


def compare_attrs(path, a, b, excluded, report):
    keys = sorted(set(a.attrs) | set(b.attrs))
    for k in keys:
        where = f"{path}@{k}"
        if excluded(where) or excluded(k):
            continue
        if k not in a.attrs or k not in b.attrs:
            report(where, "attribute only in " + ("the second" if k not in a.attrs else "the first"))
            continue
        ok, note = same_array(np.asarray(a.attrs[k]), np.asarray(b.attrs[k]))
        if not ok:
            report(where, "attribute: " + note)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("first")
    ap.add_argument("second")
    ap.add_argument("--exclude", action="append", default=None, metavar="REGEX",
                    help="skip datasets and attributes whose path matches (repeatable; replaces "
                         "the default wall-clock list)")
    ap.add_argument("--quiet", action="store_true", help="print only the differences and the summary")
    args = ap.parse_args()
    patterns = [re.compile(p) for p in (args.exclude if args.exclude is not None else DEFAULT_EXCLUDE)]

    def excluded(path):
        return any(p.search(path) for p in patterns)

    try:
        fa, fb = h5py.File(args.first, "r"), h5py.File(args.second, "r")
    except OSError as e:
        print(f"compare_h5: {e}", file=sys.stderr)
        return 2
    differences = []

    def report(path, note):
        differences.append(path)
        print(f"DIFFERS  {path}: {note}")

    with fa, fb:
        ia, ib = walk(fa), walk(fb)
        compared = skipped = 0
        for path in sorted(set(ia) | set(ib)):
            if excluded(path):
                skipped += isinstance(ia.get(path, ib.get(path)), h5py.Dataset)
                if not args.quiet:
                    print(f"skipped  {path}")
                continue
            if path not in ia or path not in ib:
                report(path, "only in " + ("the second" if path not in ia else "the first"))
                continue
            a, b = ia[path], ib[path]
            compare_attrs(path, a, b, excluded, report)
            if isinstance(a, h5py.Dataset) != isinstance(b, h5py.Dataset):
                report(path, "a dataset on one side, a group on the other")
                continue
            if not isinstance(a, h5py.Dataset):
                continue
            compared += 1
            ok, note = same_array(a[()] if a.shape != () else np.asarray(a[()]),
                                  b[()] if b.shape != () else np.asarray(b[()]))
            if ok:
                if not args.quiet:
                    print(f"same     {path}")
            else:
                report(path, note)
    print(f"compare_h5: {compared} datasets compared, {skipped} skipped, "
          f"{len(differences)} differences")
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())

"""The tools and walls in the DEM's XDMF (issue 15; docs/visualise.md), read back without ParaView:

* a dem_run of tests/visual/scene.yaml (a blade that moves on a straight line and turns at a
  constant rate through 400 spheres in a bin on a floor) and the same scene under dem_service,
  driven over the bus by prescribed_participant (cosim_master, tests/visual/cosim.yaml);
* the XDMF is one temporal collection: at every snapshot time the particles, the blade (triangles)
  and the walls (quads), each DataItem naming a dataset of the HDF5 file with the shape it says;
* the blade's triangles are the OBJ file's faces (read here from the file, as coordinates), its
  stored tool-frame vertices are the file's vertices minus the reference point;
* at every snapshot the blade's vertices are R(q) v + p of those tool-frame vertices for the
  pose recorded at that time: the closed-form pose of the keyframes, the snapshot's own pose
  attributes, under dem_service also the DEM's wrench/pose samples and the pose the prescribed
  participant sent (the master's record) at that time; all within 1e-9 m;
* the box's faces are drawn as the box's faces, the floor plane as a rectangle on the plane that
  covers every particle and blade vertex of every snapshot.
"""
import math
import os
import subprocess
import sys
import tempfile
import unittest
import xml.etree.ElementTree as ET

import h5py
import numpy as np

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
PORT = 7800 + os.getpid() % 150
HERE = os.path.join(ROOT, "tests", "visual")
TOL = 1e-9  # m; the blade is 0.2 m across, a wrong pose or frame is off by millimetres or more

# The keyframes of scene.yaml / cosim.yaml: straight line, 30 degrees about +y in 0.05 s.
P0, P1, T1 = np.array([0.03, 0.05, 0.15]), np.array([0.20, 0.05, 0.05]), 0.05
ANGLE = math.radians(30)
REFERENCE = np.array([0.1, 0.0, 0.02])  # tools[0].reference_point


def closed_form(t):
    f = min(max(t / T1, 0.0), 1.0)
    a = ANGLE * f
    R = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    return P0 + f * (P1 - P0), R


def rotation(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_obj(path):
    v, f = [], []
    for line in open(path).read().splitlines():
        p = line.split()
        if p and p[0] == "v":
            v.append([float(x) for x in p[1:4]])
        elif p and p[0] == "f":
            f.append([int(x.split("/")[0]) - 1 for x in p[1:4]])
    return np.array(v), np.array(f)


def read_xdmf(path):
    """[(time, {grid name: {'topology': (type, n, item), 'geometry': item, 'attributes': {...}}})]
    with item = (hdf5 path, dims) and the HDF5 file name."""
    root = ET.parse(path).getroot()
    top = root.find("Domain").findall("Grid")
    assert len(top) == 1, "one temporal collection"
    assert top[0].get("CollectionType") == "Temporal"
    steps = []
    for step in top[0].findall("Grid"):
        assert step.get("CollectionType") == "Spatial", step.get("Name")
        t = float(step.find("Time").get("Value"))
        grids = {}
        for g in step.findall("Grid"):
            def item(e):
                d = e.find("DataItem")
                if d is None:
                    return None
                file, where = d.text.strip().split(":", 1)
                return file, where, tuple(int(x) for x in d.get("Dimensions").split())
            topo = g.find("Topology")
            grids[g.get("Name")] = {
                "topology": (topo.get("TopologyType"), int(topo.get("NumberOfElements")), item(topo)),
                "geometry": item(g.find("Geometry")),
                "attributes": {a.get("Name"): item(a) for a in g.findall("Attribute")},
            }
        steps.append((t, grids))
    return steps


class Xdmf(unittest.TestCase):
    def check_run(self, h5path, samples_from_bus=None):
        xdmf = os.path.splitext(h5path)[0] + ".xdmf"
        steps = read_xdmf(xdmf)
        obj_v, obj_f = read_obj(os.path.join(ROOT, "configs/dem/meshes/blade.obj"))
        with h5py.File(h5path, "r") as f:
            snaps = sorted(f["particles"].keys())
            self.assertEqual(len(steps), len(snaps))
            self.assertGreaterEqual(len(steps), 11)
            times = [f["particles"][k].attrs["time"] for k in snaps]
            self.assertEqual([t for t, _ in steps], times)  # exactly: shortest round-trip text
            self.assertAlmostEqual(times[-1], T1, delta=1e-12)

            # Every DataItem names a dataset of this file with the shape the XDMF gives.
            name = os.path.basename(h5path)
            for t, grids in steps:
                self.assertEqual(list(grids), ["particles", "tool_blade", "walls"])
                for g in grids.values():
                    items = [g["topology"][2], g["geometry"]] + list(g["attributes"].values())
                    for it in items:
                        if it is None:
                            continue
                        self.assertEqual(it[0], name)
                        self.assertIn(it[1], f, it[1])
                        self.assertEqual(f[it[1]].shape, it[2], it[1])
            self.assertEqual(steps[0][1]["tool_blade"]["topology"][0], "Triangle")
            self.assertEqual(steps[0][1]["walls"]["topology"][0], "Quadrilateral")
            self.assertEqual(steps[0][1]["walls"]["topology"][1], 6)  # floor + 5 faces of the open box

            # The mesh: the OBJ's triangles as coordinates, vertices relative to the reference point.
            local = f["tools/blade/vertices"][:]
            tri = f["tools/blade/triangles"][:]
            self.assertEqual(tri.dtype, np.int32)
            # (assimp reads the file's coordinates as 32-bit floats)
            file_tris = [obj_v.astype(np.float32).astype(float)[row] for row in obj_f]
            self.assertEqual(len(tri), len(file_tris))
            for row in tri:
                corners = local[row] + REFERENCE
                same = [any(np.abs(corners - np.roll(ft, k, axis=0)).max() < 1e-12 for k in range(3))
                        for ft in file_tris]
                self.assertEqual(sum(same), 1, corners)

            all_points = []
            for k, (t, grids) in enumerate(steps):
                where = grids["tool_blade"]["geometry"][1]
                world = f[where][:]
                self.assertEqual(where, f"/tools/blade/snapshots/{snaps[k]}")
                p, R = closed_form(t)
                np.testing.assert_allclose(world, local @ R.T + p, rtol=0, atol=TOL, err_msg=f"t={t}")
                a = f[where].attrs
                self.assertEqual(a["time"], t)
                np.testing.assert_allclose(world, local @ rotation(a["orientation"]).T + a["position"],
                                           rtol=0, atol=1e-12)
                # The particles of this snapshot are the file's particles.
                pg = grids["particles"]
                self.assertEqual(pg["topology"][1], f[pg["geometry"][1]].shape[0])
                all_points += [f[pg["geometry"][1]][:], world]
            # The engine's own record of the pose (wrench samples) agrees with the closed form.
            s = f["tools/blade/samples"][:]
            self.assertGreater(len(s), 40)
            for row in s:
                p, R = closed_form(row[0])
                np.testing.assert_allclose(row[7:10], p, rtol=0, atol=TOL)
                np.testing.assert_allclose(rotation(row[10:14]), R, rtol=0, atol=1e-9)
            # The DEM's own samples at the snapshot times (dem_service samples at macro step
            # starts, where its snapshots are taken) and the pose the tool sent over the bus.
            if samples_from_bus is not None:
                sent_t, sent = samples_from_bus
                matched = 0
                for t, grids in steps:
                    world = f[grids["tool_blade"]["geometry"][1]][:]
                    row = s[np.abs(s[:, 0] - t) < 1e-12]
                    if len(row):
                        matched += 1
                        np.testing.assert_allclose(
                            world, local @ rotation(row[0, 10:14]).T + row[0, 7:10], rtol=0, atol=TOL)
                    i = np.flatnonzero(np.abs(sent_t - t) < 1e-12)
                    self.assertEqual(len(i), 1, f"t={t} in the master's record")
                    q = sent[i[0]]
                    np.testing.assert_allclose(world, local @ rotation(q[3:7]).T + q[0:3], rtol=0, atol=TOL)
                self.assertGreaterEqual(matched, len(steps) - 1)  # all but the session's end

            # Walls: the box's faces exactly; the floor on z = 0 covering everything seen.
            wv = f["wall_geometry/vertices"][:]
            quads = f["wall_geometry/quads"][:]
            names = f["wall_geometry"].attrs["names"]
            names = names.decode() if isinstance(names, bytes) else names
            self.assertEqual(names.split(", "), ["floor", "bin/xmin", "bin/xmax", "bin/ymin", "bin/ymax", "bin/zmin"])
            face = lambda i: wv[quads[i]]  # noqa: E731
            for i, (axis, value) in enumerate([(0, 0.0), (0, 0.3), (1, 0.0), (1, 0.1), (2, 0.0)], start=1):
                c = face(i)
                np.testing.assert_array_equal(c[:, axis], value)
                others = [a for a in range(3) if a != axis]
                for a in others:
                    self.assertEqual(sorted(set(c[:, a])), [0.0, [0.3, 0.1, 0.4][a]])
            floor = face(0)
            np.testing.assert_allclose(floor[:, 2], 0.0, atol=1e-15)
            pts = np.vstack(all_points)
            for a in (0, 1):
                self.assertLess(floor[:, a].min(), pts[:, a].min())
                self.assertGreater(floor[:, a].max(), pts[:, a].max())
            # ... and not absurdly larger (the margin is a tenth of the scene's size).
            span = pts.max(axis=0) - pts.min(axis=0)
            self.assertLess(floor[:, 0].max() - floor[:, 0].min(), 1.5 * max(span))

    def test_dem_run(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "run.h5")
            r = subprocess.run([os.path.join(BIN, "dem_run"), os.path.join(HERE, "scene.yaml"),
                                "--output", out], capture_output=True, text=True, cwd=tmp)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.check_run(out)

    def test_dem_service(self):
        with tempfile.TemporaryDirectory() as tmp:
            soil, master = os.path.join(tmp, "soil.h5"), os.path.join(tmp, "master.h5")
            r = subprocess.run([os.path.join(BIN, "cosim_master"), os.path.join(HERE, "cosim.yaml"),
                                "--output", master,
                                "--set", f"bus.url=udpm://239.255.76.67:{PORT}?ttl=0",
                                "--set", f"participants.dem.parameters.output.file={soil}"],
                               capture_output=True, text=True, cwd=tmp)
            self.assertEqual(r.returncode, 0, r.stdout[-3000:] + r.stderr[-3000:])
            with h5py.File(master, "r") as f:
                sent = (f["time"][:], f["participants/tool/outputs/blade"][:])
            self.check_run(soil, sent)


if __name__ == "__main__":
    unittest.main()

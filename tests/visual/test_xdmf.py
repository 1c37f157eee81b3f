"""The tools and walls in the DEM's XDMF (issue 15; docs/visualise.md), read back without ParaView:

* a dem_run of tests/visual/scene.yaml (a blade that moves on a straight line and turns at a
  constant rate through 400 spheres in a bin on a floor) and the same scene under dem_service,
  driven over the bus by prescribed_adapter (cosim_master, tests/visual/cosim.yaml);
* the XDMF is one temporal collection: at every snapshot time the particles, the blade (triangles)
  and the walls (quads), each DataItem naming a dataset of the HDF5 file with the shape it says;
* the blade's triangles are the OBJ file's faces (read here from the file, as coordinates), its
  stored tool-frame vertices are the file's vertices minus the reference point;
* at every snapshot the blade's vertices are R(q) v + p of those tool-frame vertices for the
  pose recorded at that time: the closed-form pose of the keyframes, the snapshot's own pose
  attributes, under dem_service also the DEM's wrench/pose samples and the pose the prescribed
  participant sent (the master's record) at that time; all within 1e-9 m;
* each wall is drawn as the part of its plane on the particles' side of every other wall: the
  box's faces as the faces, the floor (a plane) cut to the box's floor; with plane walls only,
  a plane covers every particle and blade vertex of every snapshot with a margin of a tenth
  of the scene and is cut where it meets the other plane.
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
    with open(path) as file:
        lines = file.read().splitlines()
    for line in lines:
        p = line.split()
        if p and p[0] == "v":
            v.append([float(x) for x in p[1:4]])
        elif p and p[0] == "f":
            f.append([int(x.split("/")[0]) - 1 for x in p[1:4]])
    return np.array(v), np.array(f)


def read_xdmf(path):
    """[(time, {grid name: {'topology': (type, n, item), 'geometry': item, 'attributes': {...}}})]
    with item = (HDF5 file name, hdf5 path, dims), and for a hyperslab its (start, stride, count,
    dims) after them."""
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
                if d.get("ItemType") == "HyperSlab":  # (start, stride, count) of a dataset
                    sel, data = d.findall("DataItem")
                    file, where = data.text.strip().split(":", 1)
                    return (file, where, tuple(int(x) for x in data.get("Dimensions").split()),
                            tuple(int(x) for x in sel.text.split()) + (int(d.get("Dimensions")),))
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

            # The particles are cells, one vertex each (without a connectivity ParaView reads
            # points but no cell, and its Surface view shows nothing): 0, 1, ..., n - 1 of
            # xdmf_point_index at every snapshot.
            for t, grids in steps:
                kind, n, conn = grids["particles"]["topology"]
                self.assertEqual(kind, "Polyvertex")
                self.assertIsNotNone(conn, "the particles' Polyvertex topology has no connectivity")
                self.assertEqual(len(conn), 4, "a hyperslab of xdmf_point_index")
                self.assertEqual(conn[1], "/xdmf_point_index")
                self.assertEqual(conn[3], (0, 1, n, n))
                np.testing.assert_array_equal(f["xdmf_point_index"][:n], np.arange(n))

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

            self.check_walls(f, steps, all_points)

    def walls(self, f):
        """{wall name: its triangles (m x 3 x 3 corners)}"""
        g = f["wall_geometry"]
        names = g.attrs["names"]
        names = (names.decode() if isinstance(names, bytes) else names).split(", ")
        v, t, owner = g["vertices"][:], g["triangles"][:], g["wall"][:]
        self.assertEqual(len(owner), len(t))
        return names, {n: v[t[owner == i]] for i, n in enumerate(names)}

    def assert_rectangle(self, tris, axis, value, lo, hi):
        """tris cover exactly the rectangle lo..hi (the two other axes) on coordinate axis = value."""
        c = tris.reshape(-1, 3)
        np.testing.assert_allclose(c[:, axis], value, rtol=0, atol=1e-12)
        others = [a for a in range(3) if a != axis]
        for a, l, h in zip(others, lo, hi):
            self.assertAlmostEqual(c[:, a].min(), l, delta=1e-12)
            self.assertAlmostEqual(c[:, a].max(), h, delta=1e-12)
        area = sum(0.5 * np.linalg.norm(np.cross(x[1] - x[0], x[2] - x[0])) for x in tris)
        self.assertAlmostEqual(area, (hi[0] - lo[0]) * (hi[1] - lo[1]), delta=1e-12)

    def check_walls(self, f, steps, all_points):
        """scene.yaml: a floor plane and an open box: each drawn as the part inside the others."""
        for t, grids in steps:
            w = grids["walls"]
            self.assertEqual(w["topology"][0], "Triangle")
            self.assertEqual(list(w["attributes"]), ["wall"])
        names, tris = self.walls(f)
        self.assertEqual(names, ["floor", "bin/xmin", "bin/xmax", "bin/ymin", "bin/ymax", "bin/zmin"])
        # The floor is cut to the box's inside, each face is the face.
        self.assert_rectangle(tris["floor"], 2, 0.0, (0.0, 0.0), (0.3, 0.1))
        self.assert_rectangle(tris["bin/zmin"], 2, 0.0, (0.0, 0.0), (0.3, 0.1))
        for name, axis, value in [("bin/xmin", 0, 0.0), ("bin/xmax", 0, 0.3), ("bin/ymin", 1, 0.0), ("bin/ymax", 1, 0.1)]:
            hi = [x for a, x in enumerate([0.3, 0.1, 0.4]) if a != axis]
            self.assert_rectangle(tris[name], axis, value, (0.0, 0.0), hi)

    def test_plane_walls_cover_the_run(self):
        """Two planes only (a floor and a back wall at x = 0.3): each is drawn over everything the
        snapshots saw (particles, blade) and cut at the other."""
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "planes.h5")
            r = subprocess.run([os.path.join(BIN, "dem_run"), os.path.join(HERE, "scene.yaml"), "--output", out,
                                "--set", "walls=[{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}, "
                                         "{name: back, type: plane, point: [0.3, 0, 0], normal: [-1, 0, 0]}]"],
                               capture_output=True, text=True, cwd=tmp)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            with h5py.File(out, "r") as f:
                pts = np.vstack([f["particles"][k]["position"][:] for k in f["particles"]] +
                                [f["tools/blade/snapshots"][k][:] for k in f["tools/blade/snapshots"]])
                names, tris = self.walls(f)
            self.assertEqual(names, ["floor", "back"])
            floor, back = tris["floor"].reshape(-1, 3), tris["back"].reshape(-1, 3)
            np.testing.assert_allclose(floor[:, 2], 0, atol=1e-15)
            np.testing.assert_allclose(back[:, 0], 0.3, atol=1e-15)
            self.assertAlmostEqual(floor[:, 0].max(), 0.3, delta=1e-12)  # cut at the back wall
            self.assertAlmostEqual(back[:, 2].min(), 0.0, delta=1e-12)   # cut at the floor
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self.assertLess(floor[:, 0].min(), lo[0])
            for c in (floor, back):
                self.assertLess(c[:, 1].min(), lo[1])
                self.assertGreater(c[:, 1].max(), hi[1])
            self.assertGreater(back[:, 2].max(), hi[2])
            # ... with a margin of a tenth of the scene, not more.
            span = (hi - lo).max()
            self.assertAlmostEqual(back[:, 2].max(), hi[2] + 0.1 * span, delta=1e-9)

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

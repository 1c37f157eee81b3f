"""scripts/render.sh and ParaView on a small run (issue 15; docs/visualise.md).

Skipped (exit 77, ctest SKIP_RETURN_CODE) with the package to install when ParaView's pvbatch,
xvfb-run or ffmpeg is missing; scripts/setup.sh installs them.

* ParaView's Xdmf3 reader (no plugins) opens the XDMF of a dem_run of tests/visual/scene.yaml:
  11 time steps, at each the particles (400 points with velocity and radius), the blade (6
  points, 4 triangles) and the walls (6 rectangles, 12 triangles); the blade's bounds in ParaView are those of its
  vertices in the HDF5 file at that time (1e-6 m), and they move;
* `render.sh RUN.xdmf --every 3 --width 320` writes 5 PNG frames (snapshots 0, 3, 6, 9 and the
  last, 10) of 320 x 180 pixels and an MP4 of 5 frames of that size (ffprobe);
* every frame has pixel variance (not blank), coloured pixels (spheres coloured by speed, not
  only the grey tool and walls on white), and the first and last frames differ (the blade moved);
* `--last` writes one picture of the last snapshot;
* refusals name the problem: a missing file, a file that is not XDMF, an XDMF whose HDF5 file is
  gone, an XDMF of the old particles-only layout, a bad --every, and no pvbatch on the PATH (names python3-paraview).
"""
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import h5py
import matplotlib.image
import numpy as np

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
HERE = os.path.join(ROOT, "tests", "visual")
RENDER = os.path.join(ROOT, "scripts", "render.sh")

missing = [(tool, pkg) for tool, pkg in [("pvbatch", "python3-paraview"), ("xvfb-run", "xvfb"),
                                         ("xauth", "xauth"), ("ffmpeg", "ffmpeg"), ("ffprobe", "ffmpeg")]
           if shutil.which(tool) is None]
if missing:
    print("SKIP: " + ", ".join(f"{t} not found (apt-get install {p})" for t, p in missing) +
          "; bash scripts/setup.sh installs them")
    sys.exit(77)


def render(*args, env=None):
    return subprocess.run(["bash", RENDER, *args], capture_output=True, text=True, env=env)


class Render(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.h5 = os.path.join(cls.tmp.name, "blade.h5")
        r = subprocess.run([os.path.join(BIN, "dem_run"), os.path.join(HERE, "scene.yaml"),
                            "--output", cls.h5], capture_output=True, text=True, cwd=cls.tmp.name)
        assert r.returncode == 0, r.stdout + r.stderr
        cls.xdmf = os.path.join(cls.tmp.name, "blade.xdmf")

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_paraview_reads_particles_tool_and_walls(self):
        r = subprocess.run(["xvfb-run", "-a", "pvbatch", os.path.join(HERE, "paraview_probe.py"), self.xdmf],
                           capture_output=True, text=True)
        lines = [l for l in r.stdout.splitlines() if l.startswith("PROBE ")]
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-2000:])
        self.assertEqual(len(lines), 1, r.stdout[-2000:])
        probe = json.loads(lines[0][len("PROBE "):])
        with h5py.File(self.h5, "r") as f:
            keys = sorted(f["particles"].keys())
            times = [f["particles"][k].attrs["time"] for k in keys]
            np.testing.assert_allclose(probe["times"], times, rtol=0, atol=1e-15)
            self.assertEqual(len(probe["steps"]), 11)
            first_tool = None
            for k, blocks in zip(keys, probe["steps"]):
                self.assertEqual(len(blocks), 3)
                p, tool, walls = blocks
                self.assertTrue(p["name"].startswith("particles"), p["name"])
                self.assertEqual(p["points"], 400)
                # One cell (a vertex) per particle: the Surface view draws them.
                self.assertEqual(p["cells"], 400)
                self.assertEqual(p["arrays"], ["velocity", "radius", "id"])
                np.testing.assert_allclose(p["bounds"][0::2], f[f"particles/{k}/position"][:].min(axis=0), atol=1e-12)
                self.assertTrue(tool["name"].startswith("tool_blade"), tool["name"])
                self.assertEqual((tool["points"], tool["cells"]), (6, 4))
                v = f[f"tools/blade/snapshots/{k}"][:]
                np.testing.assert_allclose(tool["bounds"][0::2], v.min(axis=0), rtol=0, atol=1e-6)
                np.testing.assert_allclose(tool["bounds"][1::2], v.max(axis=0), rtol=0, atol=1e-6)
                self.assertTrue(walls["name"].startswith("walls"), walls["name"])
                self.assertEqual((walls["points"], walls["cells"]), (24, 12))  # 6 rectangles
                first_tool = first_tool or tool["bounds"]
            # The blade went 0.17 m along x between the first and the last snapshot.
            self.assertGreater(tool["bounds"][0] - first_tool[0], 0.1)

    def test_frames_and_movie(self):
        out = os.path.join(self.tmp.name, "frames")
        r = render(self.xdmf, "--out", out, "--every", "3", "--width", "320")
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-2000:])
        frames = sorted(glob.glob(os.path.join(out, "blade_*.png")))
        self.assertEqual([os.path.basename(x) for x in frames], [f"blade_{i:05d}.png" for i in range(5)])
        self.assertIn("(snapshot 10)", r.stdout)  # the last snapshot is always drawn
        images = [matplotlib.image.imread(x)[:, :, :3] for x in frames]
        for name, im in zip(frames, images):
            self.assertEqual(im.shape, (180, 320, 3), name)
            self.assertGreater(im.var(), 1e-3, f"{name} is blank")
            # Coloured pixels: the spheres (coloured by speed); tool and walls are grey on white.
            saturation = im.max(axis=2) - im.min(axis=2)
            self.assertGreater((saturation > 0.25).mean(), 0.002, f"{name}: no coloured spheres")
        self.assertGreater(np.abs(images[0] - images[-1]).mean(), 0.005, "first and last frames alike")
        mp4 = os.path.join(out, "blade.mp4")
        self.assertTrue(os.path.isfile(mp4), r.stdout)
        p = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                            "-show_entries", "stream=codec_name,width,height,nb_read_frames",
                            "-of", "json", mp4], capture_output=True, text=True)
        self.assertEqual(p.returncode, 0, p.stderr)
        s = json.loads(p.stdout)["streams"][0]
        self.assertEqual((s["codec_name"], s["width"], s["height"], int(s["nb_read_frames"])),
                         ("h264", 320, 180, 5))

    def test_last_picture(self):
        out = os.path.join(self.tmp.name, "last")
        r = render(self.xdmf, "--out", out, "--last", "--width", "256")
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-2000:])
        self.assertEqual(os.listdir(out), ["blade_last.png"])
        im = matplotlib.image.imread(os.path.join(out, "blade_last.png"))
        self.assertEqual(im.shape[:2], (144, 256))
        self.assertGreater(im[:, :, :3].var(), 1e-3)

    def test_refusals(self):
        d = self.tmp.name
        r = render(os.path.join(d, "nope.xdmf"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("nope.xdmf: no such file", r.stderr)
        r = render(self.h5)
        self.assertEqual(r.returncode, 2)
        self.assertIn("not an XDMF file", r.stderr)
        r = render(self.xdmf, "--every", "0")
        self.assertEqual(r.returncode, 2)
        self.assertIn("--every '0'", r.stderr)
        r = render(self.xdmf, "--width", "321")
        self.assertIn("even number of pixels", r.stderr)
        # An XDMF whose HDF5 file is gone: named, not a ParaView crash.
        lone = os.path.join(d, "lone")
        os.makedirs(lone, exist_ok=True)
        shutil.copy(self.xdmf, lone)
        r = render(os.path.join(lone, "blade.xdmf"), "--last")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("blade.h5, which is missing", r.stderr)
        # A particles-only XDMF of the old layout (one plain grid per time step).
        old = os.path.join(lone, "old.xdmf")
        with open(old, "w") as f:
            f.write('<?xml version="1.0" ?>\n<Xdmf Version="3.0"><Domain><Grid Name="particles" '
                    'GridType="Collection" CollectionType="Temporal"><Grid Name="step0" GridType="Uniform">'
                    '<Time Value="0"/><Topology TopologyType="Polyvertex" NumberOfElements="1"/></Grid>'
                    '</Grid></Domain></Xdmf>\n')
        r = render(old, "--last")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("one plain grid per time step", r.stderr)
        # No ParaView on the PATH: the package to install.
        bare = os.path.join(d, "bin")
        os.makedirs(bare, exist_ok=True)
        for tool in ["bash", "head", "grep", "realpath", "dirname", "basename", "mkdir", "sed",
                     "mktemp", "rm", "cat", "tail"]:
            if not os.path.exists(os.path.join(bare, tool)):
                os.symlink(shutil.which(tool), os.path.join(bare, tool))
        r = render(self.xdmf, env={"PATH": bare})
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("apt-get install python3-paraview", r.stderr)


if __name__ == "__main__":
    unittest.main()

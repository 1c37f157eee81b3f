"""Run by test_render.py under `xvfb-run -a pvbatch`: opens an XDMF with ParaView's Xdmf3 reader
(no plugins) and prints, as JSON, its time steps and, per time step, every block's name, point
and cell counts and bounds."""
import json
import sys

from paraview.simple import Xdmf3ReaderT, servermanager

reader = Xdmf3ReaderT(FileName=[sys.argv[1]])
out = {"times": list(reader.TimestepValues), "steps": []}
for t in out["times"]:
    reader.UpdatePipeline(t)
    d = servermanager.Fetch(reader)
    blocks = []
    for i in range(d.GetNumberOfBlocks()):
        b = d.GetBlock(i)
        blocks.append({"name": d.GetMetaData(i).Get(d.NAME()), "points": b.GetNumberOfPoints(),
                       "cells": b.GetNumberOfCells(), "bounds": list(b.GetBounds()),
                       "arrays": [b.GetPointData().GetArrayName(k)
                                  for k in range(b.GetPointData().GetNumberOfArrays())]})
    out["steps"].append(blocks)
print("PROBE " + json.dumps(out))

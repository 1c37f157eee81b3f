#!/usr/bin/python3
"""The layering of the sources (docs/protocol.md#layers): no include from a lower layer to a
higher one, and the DEM engine and the participant API without the bus's wire types.

  check_layering.py SOURCE_DIR [BIN_DIR]

Reads every #include of the C++ sources and checks:
  * protocol/support (the bus-free floor) includes no bus header (protocol/include), no LCM and
    no message type, and nothing of dem/, mbs/, master;
  * protocol/ (the bus) includes nothing of dem_service, mbs_adapters, master or fmu_export;
  * the DEM engine (dem_service: every source but the participant, service.* and
    apps/dem_service.cpp) includes no bus header, no LCM, no message type, nothing of the
    machines or the master;
  * the participant API a model includes (cosim/participant.hpp) reaches no message type and no
    LCM header through its includes;
  * the machines include nothing of the DEM, the DEM nothing of the machines;
  * no include cycle among the project's headers.
With BIN_DIR: dem_run, dem_lab and soil_wedge (the engine's programs) hold no LCM symbol.
Exit 0 when all hold, 1 with one line per breach.
"""
import os
import re
import subprocess
import sys

SRC = os.path.abspath(sys.argv[1])
BIN = sys.argv[2] if len(sys.argv) > 2 else None
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)
EXTS = (".hpp", ".h", ".cpp", ".cc", ".c", ".inc")

SUPPORT_INC = os.path.join(SRC, "protocol/support/include")
BUS_INC = os.path.join(SRC, "protocol/include")


def headers_in(folder):
    out = set()
    for root, _, files in os.walk(folder):
        for f in files:
            if f.endswith(EXTS):
                out.add(os.path.relpath(os.path.join(root, f), folder))
    return out


def sources(folder):
    for root, _, files in os.walk(os.path.join(SRC, folder)):
        for f in sorted(files):
            if f.endswith(EXTS):
                yield os.path.join(root, f)


def includes(path):
    with open(path, encoding="utf-8", errors="replace") as fh:
        return INCLUDE.findall(fh.read())


SUPPORT = headers_in(SUPPORT_INC)
BUS = headers_in(BUS_INC)
# The LCM message types (generated as cosim/<name>.hpp from lcmtypes/*.lcm).
MESSAGES = set()
for f in os.listdir(os.path.join(SRC, "lcmtypes")):
    if f.endswith(".lcm"):
        with open(os.path.join(SRC, "lcmtypes", f)) as fh:
            MESSAGES |= {"cosim/%s.hpp" % m for m in re.findall(r"\bstruct\s+(\w+)", fh.read())}

problems = []


def rel(p):
    return os.path.relpath(p, SRC)


def is_wire(inc):
    return inc in MESSAGES or inc.startswith("lcm/")


def check(folder, forbidden, why, skip=()):
    n = 0
    for path in sources(folder):
        if any(rel(path).startswith(s) for s in skip):
            continue
        n += 1
        for inc in includes(path):
            if forbidden(inc):
                problems.append("%s includes %s (%s)" % (rel(path), inc, why))
    if n == 0:
        problems.append("%s: no sources found (moved? update tests/layering)" % folder)


# Sanity: the lists the rules rest on are what they should be.
for h in ("cosim/yaml_config.hpp", "cosim/quantities.hpp", "cosim/h5.hpp", "cosim/time.hpp"):
    if h not in SUPPORT:
        problems.append("protocol/support/include lacks %s" % h)
for h in ("cosim/participant.hpp", "cosim/signal_wire.hpp", "cosim/sealed_bus.hpp"):
    if h not in BUS:
        problems.append("protocol/include lacks %s" % h)
if len(MESSAGES) < 5:
    problems.append("lcmtypes/: found only %d message types" % len(MESSAGES))
if SUPPORT & BUS:
    problems.append("headers in both protocol/include and protocol/support/include: %s"
                    % sorted(SUPPORT & BUS))

HIGHER = re.compile(r"^(dem|mbs|master|fmu|common|wheel_loader|hauler)/")
check("protocol/support", lambda i: i in BUS or is_wire(i) or bool(HIGHER.match(i)),
      "the bus-free support reaches the bus or a higher layer")
check("protocol/src", lambda i: bool(HIGHER.match(i)), "the bus reaches a higher layer")
check("protocol/include", lambda i: bool(HIGHER.match(i)), "the bus reaches a higher layer")

ENGINE_SKIP = ("dem_service/src/service.cpp", "dem_service/include/dem/service.hpp",
               "dem_service/apps/dem_service.cpp", "dem_service/src/mpi/service_ranks.cpp",
               "dem_service/include/dem/mpi/service_ranks.hpp")
engine_forbidden = lambda i: (i in BUS or is_wire(i) or i.startswith("mbs/")
                              or i.startswith("master/") or "simbody" in i.lower())
for folder in ("dem_service/src", "dem_service/include", "dem_service/apps"):
    check(folder, engine_forbidden, "the DEM engine reaches the bus or the machines", ENGINE_SKIP)

# The engine knows nothing of MPI (docs/mpi.md): only the MPI driver (dem_service/src/mpi,
# dem_service/include/dem/mpi) includes mpi.h, and its header does not; the engine's own files
# include neither mpi.h nor the driver.
MPI_SKIP = ("dem_service/src/mpi/", "dem_service/include/dem/mpi/")
is_mpi = lambda i: i == "mpi.h" or i.startswith("openmpi/") or i.startswith("mpi/")
for folder in ("dem_service/src", "dem_service/include"):
    check(folder, lambda i: is_mpi(i) or i.startswith("dem/mpi/"),
          "the DEM engine reaches MPI (only dem_service/src/mpi may)", MPI_SKIP)
check("dem_service/include/dem/mpi", is_mpi,
      "the MPI driver's header names MPI (its programs include it without mpi.h)")
check("dem_service/apps", is_mpi, "a DEM program includes mpi.h (dem/mpi/ wraps it)")
check("dem_service/src/mpi", lambda i: False, "")  # it exists (a move would need this file updated)

check("mbs_adapters", lambda i: i.startswith("dem/"), "a machine reaches the DEM")

# What participant.hpp reaches, header by header (the project's own headers resolved).
def resolve(inc):
    for base in (SUPPORT_INC, BUS_INC):
        p = os.path.join(base, inc)
        if os.path.exists(p):
            return p
    return None


seen, todo = set(), ["cosim/participant.hpp"]
while todo:
    h = todo.pop()
    if h in seen:
        continue
    seen.add(h)
    p = resolve(h)
    if p is None:
        continue
    for inc in includes(p):
        if is_wire(inc):
            problems.append("cosim/participant.hpp reaches %s through %s (the participant API "
                            "a model includes holds no wire type)" % (inc, h))
        todo.append(inc)

# Include cycles among the project's headers (each header's quoted or cosim/dem includes).
graph = {}
for folder in ("protocol", "dem_service/include", "mbs_adapters", "master/src"):
    for path in sources(folder):
        if path.endswith((".hpp", ".h")):
            graph[path] = []
by_name = {}
for path in graph:
    for base in (SUPPORT_INC, BUS_INC, os.path.join(SRC, "dem_service/include")):
        if path.startswith(base + os.sep):
            by_name[os.path.relpath(path, base)] = path
for path in graph:
    for inc in includes(path):
        target = by_name.get(inc) or os.path.join(os.path.dirname(path), inc)
        if target in graph:
            graph[path].append(target)
state = {}


def visit(node, stack):
    state[node] = 1
    stack.append(node)
    for nxt in graph[node]:
        if state.get(nxt) == 1:
            cycle = stack[stack.index(nxt):] + [nxt]
            problems.append("include cycle: " + " -> ".join(rel(c) for c in cycle))
        elif nxt not in state:
            visit(nxt, stack)
    stack.pop()
    state[node] = 2


for node in sorted(graph):
    if node not in state:
        visit(node, [])

if BIN:
    for prog in ("dem_run", "dem_lab", "soil_wedge"):
        path = os.path.join(BIN, prog)
        if not os.path.exists(path):
            problems.append("%s: not built" % path)
            continue
        syms = subprocess.run(["nm", "-C", path], capture_output=True, text=True).stdout
        lcm = [l for l in syms.splitlines() if re.search(r"\blcm_|\blcm::|cosim::\w+_t\b", l)]
        if lcm:
            problems.append("%s links the bus: %d LCM symbols, e.g. %s"
                            % (prog, len(lcm), lcm[0].split()[-1]))

for p in problems:
    print("layering: " + p)
if problems:
    sys.exit(1)
print("layering: %d support headers, %d bus headers, %d message types; every rule holds"
      % (len(SUPPORT), len(BUS), len(MESSAGES)))

/* A test-only FMI 3.0 co-simulation FMU with arrays and a structural parameter, for the
 * importer's tests; written from the FMI 3.0 standard, not a model.
 * Value references: 0 time; 1 n (UInt64 structural parameter, the length of u and y, 1..8);
 * 2 u (Float64 input [n]); 3 y (Float64 output [n], y = scale * u at each step's start);
 * 4 scale (Float64 tunable parameter); 5 offsets (Int32 fixed parameter [2]);
 * 6 total (Float64 output: sum(u) + offsets[0] + offsets[1]); 7 stop_at (Float64 fixed parameter:
 * the doStep that would pass it stops there and returns fmi3Discard with terminateSimulation). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_fmi3.h"

#define EXPORT __attribute__((visibility("default")))
#define NMAX 8

typedef struct {
  fmi3InstanceEnvironment env;
  fmi3LogMessageCallback log;
  int configuring;
  double time, u[NMAX], y[NMAX], scale, total, stop_at;
  uint64_t n;
  int32_t offsets[2];
} Instance;

static fmi3Status fail(Instance* in, const char* text) {
  if (in->log) in->log(in->env, fmi3Error, "logStatusError", text);
  return fmi3Error;
}

EXPORT const char* fmi3GetVersion(void) { return "3.0"; }

EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                                fmi3Boolean logging, fmi3Boolean event_mode, fmi3Boolean early_return,
                                                const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
                                                fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback update) {
  (void)name; (void)resources; (void)visible; (void)logging; (void)req; (void)nreq; (void)update;
  if (!token || strcmp(token, "{array-fmu3-test-0001}") != 0 || event_mode || early_return) return NULL;
  Instance* in = (Instance*)calloc(1, sizeof(Instance));
  if (!in) return NULL;
  in->env = env;
  in->log = log;
  in->n = 3;
  in->scale = 2;
  in->stop_at = 1e300;
  return in;
}
EXPORT void fmi3FreeInstance(fmi3Instance c) { free(c); }
EXPORT fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { ((Instance*)c)->configuring = 1; return fmi3OK; }
EXPORT fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { ((Instance*)c)->configuring = 0; return fmi3OK; }
EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean td, fmi3Float64 tol, fmi3Float64 start,
                                              fmi3Boolean sd, fmi3Float64 stop) {
  (void)td; (void)tol; (void)sd; (void)stop;
  ((Instance*)c)->time = start;
  return fmi3OK;
}
static void outputs(Instance* in) {
  in->total = in->offsets[0] + in->offsets[1];
  for (uint64_t i = 0; i < in->n; ++i) {
    in->y[i] = in->scale * in->u[i];
    in->total += in->u[i];
  }
}
EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance c) { outputs((Instance*)c); return fmi3OK; }
EXPORT fmi3Status fmi3Terminate(fmi3Instance c) { (void)c; return fmi3OK; }
EXPORT fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean nsp, fmi3Boolean* event,
                             fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
  (void)nsp;
  Instance* in = (Instance*)c;
  if (t < in->time - 1e-9 || t > in->time + 1e-9) return fail(in, "doStep at the wrong time");
  outputs(in);
  *event = 0;
  *early = 0;
  if (t + h > in->stop_at + 1e-12) {
    in->time = in->stop_at > t ? in->stop_at : t;
    *terminate = 1;
    *last = in->time;
    return fmi3Discard;
  }
  in->time = t + h;
  *terminate = 0;
  *last = in->time;
  return fmi3OK;
}

EXPORT fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[], size_t nv) {
  Instance* in = (Instance*)c;
  size_t k = 0;
  for (size_t i = 0; i < nvr; ++i) {
    const double* src = NULL;
    size_t m = 1;
    if (vr[i] == 0) src = &in->time;
    else if (vr[i] == 2) { src = in->u; m = in->n; }
    else if (vr[i] == 3) { src = in->y; m = in->n; }
    else if (vr[i] == 4) src = &in->scale;
    else if (vr[i] == 6) src = &in->total;
    else if (vr[i] == 7) src = &in->stop_at;
    else return fail(in, "fmi3GetFloat64: unknown value reference");
    if (k + m > nv) return fail(in, "fmi3GetFloat64: nValues too small for the arrays");
    memcpy(v + k, src, m * sizeof(double));
    k += m;
  }
  return k == nv ? fmi3OK : fail(in, "fmi3GetFloat64: nValues does not match the arrays' sizes");
}
EXPORT fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 v[], size_t nv) {
  Instance* in = (Instance*)c;
  size_t k = 0;
  for (size_t i = 0; i < nvr; ++i) {
    if (vr[i] == 2) {
      if (k + in->n > nv) return fail(in, "fmi3SetFloat64: u needs n values");
      memcpy(in->u, v + k, in->n * sizeof(double));
      k += in->n;
    } else if (vr[i] == 4) {
      in->scale = v[k++];
    } else if (vr[i] == 7) {
      in->stop_at = v[k++];
    } else {
      return fail(in, "fmi3SetFloat64: not an input or parameter");
    }
  }
  return k == nv ? fmi3OK : fail(in, "fmi3SetFloat64: nValues does not match the arrays' sizes");
}
EXPORT fmi3Status fmi3GetUInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 v[], size_t nv) {
  Instance* in = (Instance*)c;
  if (nvr != 1 || nv != 1 || vr[0] != 1) return fail(in, "fmi3GetUInt64: only n");
  v[0] = in->n;
  return fmi3OK;
}
EXPORT fmi3Status fmi3SetUInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 v[], size_t nv) {
  Instance* in = (Instance*)c;
  if (nvr != 1 || nv != 1 || vr[0] != 1) return fail(in, "fmi3SetUInt64: only n");
  if (!in->configuring) return fail(in, "n is a structural parameter: set it in Configuration Mode");
  if (v[0] < 1 || v[0] > NMAX) return fail(in, "n must be 1..8");
  in->n = v[0];
  return fmi3OK;
}
EXPORT fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 v[], size_t nv) {
  Instance* in = (Instance*)c;
  if (nvr != 1 || nv != 2 || vr[0] != 5) return fail(in, "fmi3GetInt32: only offsets (2 values)");
  v[0] = in->offsets[0];
  v[1] = in->offsets[1];
  return fmi3OK;
}
EXPORT fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[], size_t nv) {
  Instance* in = (Instance*)c;
  if (nvr != 1 || nv != 2 || vr[0] != 5) return fail(in, "fmi3SetInt32: only offsets (2 values)");
  in->offsets[0] = v[0];
  in->offsets[1] = v[1];
  return fmi3OK;
}

#define UNUSED_GETSET(T)                                                                                              \
  EXPORT fmi3Status fmi3Get##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3##T v[], size_t nv) {   \
    (void)vr; (void)v; (void)nv;                                                                                      \
    return nvr == 0 ? fmi3OK : fail((Instance*)c, "no such variable");                                                \
  }                                                                                                                   \
  EXPORT fmi3Status fmi3Set##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3##T v[], size_t nv) { \
    (void)vr; (void)v; (void)nv;                                                                                      \
    return nvr == 0 ? fmi3OK : fail((Instance*)c, "no such variable");                                               \
  }
UNUSED_GETSET(Float32)
UNUSED_GETSET(Int8)
UNUSED_GETSET(UInt8)
UNUSED_GETSET(Int16)
UNUSED_GETSET(UInt16)
UNUSED_GETSET(UInt32)
UNUSED_GETSET(Int64)
UNUSED_GETSET(Boolean)
UNUSED_GETSET(String)
EXPORT fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, size_t s[], fmi3Binary v[], size_t nv) {
  (void)vr; (void)s; (void)v; (void)nv;
  return nvr == 0 ? fmi3OK : fail((Instance*)c, "no such variable");
}
EXPORT fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const size_t s[], const fmi3Binary v[], size_t nv) {
  (void)vr; (void)s; (void)v; (void)nv;
  return nvr == 0 ? fmi3OK : fail((Instance*)c, "no such variable");
}

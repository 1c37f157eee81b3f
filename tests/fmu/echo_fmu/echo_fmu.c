/* A test-only FMI 2.0 co-simulation FMU for the importer's mapping tests: each doStep copies the
 * inputs as they were at the step's start to the outputs (y_i = u_i, n_out = n, b_out = b) and
 * integrates s' = u0 exactly for held inputs (s += u0 h), so its state matters for repeated
 * steps. It can save and restore its state (fmi2GetFMUstate/SetFMUstate). Written for the tests
 * from the FMI 2.0 standard; not a model.
 * Value references: 0 time; 1..16 u0..u15 (Real inputs); 17..32 y0..y15 (Real outputs);
 * 33 s (Real output); 40 n (Integer input); 41 b (Boolean input); 42 n_out; 43 b_out. */
#include <stdlib.h>
#include <string.h>

#include "cosim_fmi2.h"

#define EXPORT __attribute__((visibility("default")))
#define N 16

typedef struct {
  double time, u[N], y[N], s;
  int n, n_out, b, b_out;
} State;

typedef struct {
  fmi2CallbackFunctions cb;
  State st;
} Instance;

EXPORT const char* fmi2GetTypesPlatform(void) { return COSIM_FMI2_TYPES_PLATFORM; }
EXPORT const char* fmi2GetVersion(void) { return COSIM_FMI2_VERSION; }
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
  (void)c; (void)on; (void)n; (void)cats;
  return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logging) {
  (void)name; (void)resources; (void)visible; (void)logging;
  if (type != fmi2CoSimulation || !guid || strcmp(guid, "{echo-fmu-test-0001}") != 0) return NULL;
  Instance* s = (Instance*)calloc(1, sizeof(Instance));
  if (s) s->cb = *cb;
  return s;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }
EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                                      fmi2Boolean sd, fmi2Real stop) {
  (void)td; (void)tol; (void)sd; (void)stop;
  ((Instance*)c)->st.time = start;
  return fmi2OK;
}
EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  State* s = &((Instance*)c)->st;
  memcpy(s->y, s->u, sizeof s->y);
  s->n_out = s->n;
  s->b_out = s->b;
  return fmi2OK;
}
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Reset(fmi2Component c) { (void)c; return fmi2OK; }

static double* real_ref(State* s, fmi2ValueReference vr) {
  if (vr == 0) return &s->time;
  if (vr >= 1 && vr <= N) return &s->u[vr - 1];
  if (vr >= N + 1 && vr <= 2 * N) return &s->y[vr - N - 1];
  if (vr == 33) return &s->s;
  return NULL;
}

static int* int_ref(State* s, fmi2ValueReference vr) {
  if (vr == 40) return &s->n;
  if (vr == 41) return &s->b;
  if (vr == 42) return &s->n_out;
  if (vr == 43) return &s->b_out;
  return NULL;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
  for (size_t i = 0; i < n; ++i) {
    double* p = real_ref(&((Instance*)c)->st, vr[i]);
    if (!p) return fmi2Error;
    v[i] = *p;
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] < 1 || vr[i] > N) return fmi2Error; /* inputs only */
    *real_ref(&((Instance*)c)->st, vr[i]) = v[i];
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
  for (size_t i = 0; i < n; ++i) {
    int* p = int_ref(&((Instance*)c)->st, vr[i]);
    if (!p || vr[i] == 41 || vr[i] == 43) return fmi2Error;
    v[i] = *p;
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 40) return fmi2Error;
    ((Instance*)c)->st.n = v[i];
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 41 && vr[i] != 43) return fmi2Error;
    v[i] = *int_ref(&((Instance*)c)->st, vr[i]);
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 41 || (v[i] != fmi2True && v[i] != fmi2False)) return fmi2Error;
    ((Instance*)c)->st.b = v[i];
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_state) {
  (void)no_set_state;
  Instance* in = (Instance*)c;
  State* s = &in->st;
  if (t < s->time - 1e-9 || t > s->time + 1e-9) {
    in->cb.logger(in->cb.componentEnvironment, "echo", fmi2Error, "logStatusError",
                  "doStep at t = %.17g but the FMU is at %.17g", t, s->time);
    return fmi2Error;
  }
  memcpy(s->y, s->u, sizeof s->y);
  s->n_out = s->n;
  s->b_out = s->b;
  s->s += s->u[0] * h;
  s->time = t + h;
  return fmi2OK;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) {
  Instance* in = (Instance*)c;
  if (!*state) *state = in->cb.allocateMemory(1, sizeof(State));
  if (!*state) return fmi2Error;
  memcpy(*state, &in->st, sizeof(State));
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
  if (!state) return fmi2Error;
  memcpy(&((Instance*)c)->st, state, sizeof(State));
  return fmi2OK;
}
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) {
  if (*state) ((Instance*)c)->cb.freeMemory(*state);
  *state = NULL;
  return fmi2OK;
}

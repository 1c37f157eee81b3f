/* A test-only FMI 2.0 co-simulation FMU that fails on purpose: its output x is the time, and
 * the doStep that would pass the parameter fail_at returns the status in fail_status (2 =
 * fmi2Discard, 3 = fmi2Error, 4 = fmi2Fatal) after logging why. Written for the importer's
 * tests from the FMI 2.0 standard; not a model. Variables (value references): 0 time,
 * 1 x (output), 2 fail_at (parameter, Real), 3 fail_status (parameter, Integer). */
#include <stdlib.h>
#include <string.h>

#include "cosim_fmi2.h"

#define EXPORT __attribute__((visibility("default")))

typedef struct {
  fmi2CallbackFunctions cb;
  char name[64];
  double time;
  double fail_at;
  int fail_status;
} Instance;

EXPORT const char* fmi2GetTypesPlatform(void) { return COSIM_FMI2_TYPES_PLATFORM; }
EXPORT const char* fmi2GetVersion(void) { return COSIM_FMI2_VERSION; }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
  (void)c; (void)on; (void)n; (void)cats;
  return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logging) {
  (void)resources; (void)visible; (void)logging;
  if (type != fmi2CoSimulation || !guid || strcmp(guid, "{fail-fmu-test-0001}") != 0) return NULL;
  Instance* s = (Instance*)calloc(1, sizeof(Instance));
  if (!s) return NULL;
  s->cb = *cb;
  strncpy(s->name, name ? name : "?", sizeof s->name - 1);
  s->fail_at = 1e300;
  s->fail_status = fmi2Error;
  return s;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                                      fmi2Boolean sd, fmi2Real stop) {
  (void)td; (void)tol; (void)sd; (void)stop;
  ((Instance*)c)->time = start;
  return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Reset(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
  Instance* s = (Instance*)c;
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == 0 || vr[i] == 1) v[i] = s->time;
    else if (vr[i] == 2) v[i] = s->fail_at;
    else return fmi2Error;
  }
  return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
  Instance* s = (Instance*)c;
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == 2) s->fail_at = v[i];
    else return fmi2Error;
  }
  return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
  Instance* s = (Instance*)c;
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == 3) v[i] = s->fail_status;
    else return fmi2Error;
  }
  return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
  Instance* s = (Instance*)c;
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == 3) s->fail_status = v[i];
    else return fmi2Error;
  }
  return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
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
  Instance* s = (Instance*)c;
  if (t + h > s->fail_at + 1e-12) {
    const fmi2Status st = (fmi2Status)s->fail_status;
    s->cb.logger(s->cb.componentEnvironment, s->name, st, "logStatusError",
                 "deliberate failure: the step from t = %g to %g passes fail_at = %g", t, t + h, s->fail_at);
    return st;
  }
  s->time = t + h;
  return fmi2OK;
}

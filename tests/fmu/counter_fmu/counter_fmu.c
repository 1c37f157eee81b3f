/* A test-only FMI 2.0 co-simulation FMU that ends itself and reads a resource file, for the
 * importer's tests; written from the FMI 2.0 standard, not a model.
 * - fmi2Instantiate takes the resource location as a file URI (RFC 3986/8089), percent-decodes
 *   it and reads the rate from <resources>/rate.txt; without that file it logs why and returns
 *   NULL (so a wrongly encoded location fails, as it does for a real FMU that reads resources).
 * - count' = rate, integrated exactly: count(t) = rate (t - t_start).
 * - The doStep that would pass the parameter stop_at advances to stop_at only and returns
 *   fmi2Discard, as a Modelica terminate() does. With the parameter terminate true (default)
 *   fmi2GetBooleanStatus(fmi2Terminated) is then true and fmi2GetRealStatus(fmi2LastSuccessfulTime)
 *   is stop_at; with terminate false it is a plain discard (the step could not be completed).
 * - Its state can be saved, restored and serialized (canSerializeFMUstate="true").
 * Value references: 0 time, 1 count (Real output), 2 rate_out (Real output), 3 stop_at (Real
 * parameter), 4 terminate (Boolean parameter). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_fmi2.h"

#define EXPORT __attribute__((visibility("default")))
#define MAGIC 0x434f554eu /* "COUN" */

typedef struct {
  double time, count, rate, stop_at;
  int terminate, terminated;
} State;

typedef struct {
  fmi2CallbackFunctions cb;
  char name[64];
  State st;
} Instance;

static void say(Instance* in, fmi2Status status, const char* text, const char* arg) {
  in->cb.logger(in->cb.componentEnvironment, in->name, status, status == fmi2OK ? "logEvents" : "logStatusError",
                text, arg);
}

EXPORT const char* fmi2GetTypesPlatform(void) { return COSIM_FMI2_TYPES_PLATFORM; }
EXPORT const char* fmi2GetVersion(void) { return COSIM_FMI2_VERSION; }
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
  (void)c; (void)on; (void)n; (void)cats;
  return fmi2OK;
}

static int hex(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logging) {
  (void)visible; (void)logging;
  if (type != fmi2CoSimulation || !guid || strcmp(guid, "{counter-fmu-test-0001}") != 0) return NULL;
  Instance* in = (Instance*)calloc(1, sizeof(Instance));
  if (!in) return NULL;
  in->cb = *cb;
  strncpy(in->name, name ? name : "?", sizeof in->name - 1);
  in->st.stop_at = 1e300;
  in->st.terminate = 1;
  /* file:///path or file://host/path (host empty or localhost); decode %XX. */
  char path[4096];
  size_t n = 0;
  const char* p = resources ? resources : "";
  if (strncmp(p, "file://", 7) != 0) {
    say(in, fmi2Error, "resource location '%s' is not a file URI", p);
    free(in);
    return NULL;
  }
  p += 7;
  if (strncmp(p, "localhost/", 10) == 0) p += 9;
  for (; *p && n + 1 < sizeof path; ++p) {
    if (*p == '%') {
      const int a = hex(p[1]), b = a < 0 ? -1 : hex(p[2]);
      if (a < 0 || b < 0) {
        say(in, fmi2Error, "resource location '%s' has a '%%' that is not followed by two hex digits", resources);
        free(in);
        return NULL;
      }
      path[n++] = (char)(a * 16 + b);
      p += 2;
    } else {
      path[n++] = *p;
    }
  }
  path[n] = '\0';
  if (n > 0 && path[n - 1] != '/' && n + 1 < sizeof path) strcat(path, "/");
  if (strlen(path) + 9 >= sizeof path) { free(in); return NULL; }
  strcat(path, "rate.txt");
  FILE* f = fopen(path, "r");
  if (!f || fscanf(f, "%lf", &in->st.rate) != 1) {
    say(in, fmi2Error, "cannot read the resource file '%s'", path);
    if (f) fclose(f);
    free(in);
    return NULL;
  }
  fclose(f);
  return in;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }
EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                                      fmi2Boolean sd, fmi2Real stop) {
  (void)td; (void)tol; (void)sd; (void)stop;
  ((Instance*)c)->st.time = start;
  return fmi2OK;
}
EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Reset(fmi2Component c) { (void)c; return fmi2Error; }

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
  State* s = &((Instance*)c)->st;
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == 0) v[i] = s->time;
    else if (vr[i] == 1) v[i] = s->count;
    else if (vr[i] == 2) v[i] = s->rate;
    else if (vr[i] == 3) v[i] = s->stop_at;
    else return fmi2Error;
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 3) return fmi2Error;
    ((Instance*)c)->st.stop_at = v[i];
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
}
EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
  (void)c; (void)vr; (void)v;
  return n == 0 ? fmi2OK : fmi2Error;
}
EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 4) return fmi2Error;
    v[i] = ((Instance*)c)->st.terminate;
  }
  return fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] != 4) return fmi2Error;
    ((Instance*)c)->st.terminate = v[i] != fmi2False;
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
  if (s->terminated) return fmi2Error;
  if (t < s->time - 1e-9 || t > s->time + 1e-9) return fmi2Error;
  if (t + h > s->stop_at + 1e-12) {
    const double reach = s->stop_at > t ? s->stop_at : t;
    s->count += s->rate * (reach - t);
    s->time = reach;
    s->terminated = s->terminate;
    say(in, fmi2OK, "%s at stop_at", s->terminate ? "terminate()" : "cannot step past");
    return fmi2Discard;
  }
  s->count += s->rate * h;
  s->time = t + h;
  return fmi2OK;
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status* v) {
  (void)c; (void)k; (void)v;
  return fmi2Discard;
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real* v) {
  if (k != fmi2LastSuccessfulTime) return fmi2Discard;
  *v = ((Instance*)c)->st.time;
  return fmi2OK;
}
EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v) {
  if (k != fmi2Terminated) return fmi2Discard;
  *v = ((Instance*)c)->st.terminated ? fmi2True : fmi2False;
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
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t* size) {
  (void)c; (void)state;
  *size = sizeof(unsigned) + sizeof(State);
  return fmi2OK;
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size) {
  (void)c;
  const unsigned magic = MAGIC;
  if (!state || size != sizeof magic + sizeof(State)) return fmi2Error;
  memcpy(out, &magic, sizeof magic);
  memcpy(out + sizeof magic, state, sizeof(State));
  return fmi2OK;
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate* state) {
  Instance* inst = (Instance*)c;
  unsigned magic = 0;
  if (size != sizeof magic + sizeof(State)) return fmi2Error;
  memcpy(&magic, in, sizeof magic);
  if (magic != MAGIC) return fmi2Error;
  if (!*state) *state = inst->cb.allocateMemory(1, sizeof(State));
  if (!*state) return fmi2Error;
  memcpy(*state, in + sizeof magic, sizeof(State));
  return fmi2OK;
}

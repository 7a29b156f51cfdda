/* A stand-in for Force Dimension's DHD library (libdhd.so): the same C functions the
 * haptics-server's `dhd` backend binds (signatures as in dhdc.h, SDK 3.x: a trailing `char ID`
 * on per-device calls), a simulated device. Built by the test suite
 * (haptics-server/tests/it/dhd.rs) with the `cc` crate; never shipped.
 *
 * The "device" is a stylus (mass 0.05 kg) held by a hand spring of 200 N/m and 5 N·s/m toward
 * the origin and pushed by the force set with dhdSetForce once dhdEnableForce(DHD_ON) was
 * called. It is integrated on the monotonic clock whenever the position is read (sub-steps of
 * at most 0.25 ms, at most 50 ms of catch-up), so any caller rate works. Units are the
 * vendor's: m, m/s, N.
 *
 * Compile-time variants (-D):
 *   STANDIN_TYPE=n       dhdGetSystemType() (default 35, omega.7: with a wrist)
 *   STANDIN_NO_DEVICE    dhdGetDeviceCount() = 0 and dhdOpen() fails as with nothing plugged in
 *   STANDIN_SWAP_XY      the motors push x where y is commanded and y where x is (a wiring error)
 *   OMIT_SETFORCE        leave out dhdSetForce (tests of the missing-symbol error)
 */
#include <math.h>
#include <string.h>
#include <time.h>

#ifndef STANDIN_TYPE
#define STANDIN_TYPE 35
#endif

static const char *last_error = "no error";
static int opened, force_on, have_t;
static double pos[3], vel[3], force[3];
static struct timespec last_t;
static long sets;

const char *dhdErrorGetLastStr(void) { return last_error; }

int dhdGetDeviceCount(void) {
#ifdef STANDIN_NO_DEVICE
    return 0;
#else
    return 1;
#endif
}

int dhdOpen(void) {
#ifdef STANDIN_NO_DEVICE
    last_error = "no device found";
    return -1;
#else
    opened = 1;
    have_t = 0;
    memset(pos, 0, sizeof pos);
    memset(vel, 0, sizeof vel);
    memset(force, 0, sizeof force);
    return 0;
#endif
}

int dhdOpenID(char id) {
    if (id != 0) {
        last_error = "invalid index";
        return -1;
    }
    return dhdOpen();
}

int dhdClose(char id) { (void)id; opened = 0; force_on = 0; return 0; }
int dhdGetSystemType(char id) { (void)id; return opened ? STANDIN_TYPE : -1; }
const char *dhdGetSystemName(char id) { (void)id; return "omega.7 (stand-in)"; }
void dhdGetSDKVersion(int *major, int *minor, int *release, int *revision) {
    *major = 3; *minor = 17; *release = 0; *revision = 9999;
}

int dhdEnableForce(unsigned char val, char id) {
    (void)id;
    if (!opened) { last_error = "device not open"; return -1; }
    force_on = val != 0;
    if (!force_on) memset(force, 0, sizeof force);
    return 0;
}

static void advance(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    if (!have_t) { last_t = now; have_t = 1; return; }
    double dt = (double)(now.tv_sec - last_t.tv_sec) + (double)(now.tv_nsec - last_t.tv_nsec) * 1e-9;
    last_t = now;
    if (dt > 0.05) dt = 0.05;
    const double m = 0.05, k = 200.0, b = 5.0;
    while (dt > 0.0) {
        double h = dt < 0.00025 ? dt : 0.00025;
        for (int i = 0; i < 3; i++) {
            double f = force_on ? force[i] : 0.0;
            double a = (-k * pos[i] - b * vel[i] + f) / m;
            vel[i] += a * h;
            pos[i] += vel[i] * h;
        }
        dt -= h;
    }
}

int dhdGetPosition(double *px, double *py, double *pz, char id) {
    (void)id;
    if (!opened) { last_error = "device not open"; return -1; }
    advance();
    *px = pos[0]; *py = pos[1]; *pz = pos[2];
    return 0;
}

int dhdGetLinearVelocity(double *vx, double *vy, double *vz, char id) {
    (void)id;
    *vx = vel[0]; *vy = vel[1]; *vz = vel[2];
    return 0;
}

int dhdGetOrientationFrame(double matrix[3][3], char id) {
    (void)id;
    /* A wrist turned about z by a tenth of the x position (radians per metre × 100). */
    double a = pos[0] * 10.0, c = cos(a), s = sin(a);
    double m[3][3] = {{c, -s, 0}, {s, c, 0}, {0, 0, 1}};
    memcpy(matrix, m, sizeof m);
    return 0;
}

unsigned int dhdGetButtonMask(char id) { (void)id; return 0; }

#ifndef OMIT_SETFORCE
int dhdSetForce(double fx, double fy, double fz, char id) {
    (void)id;
    if (!opened) { last_error = "device not open"; return -1; }
#ifdef STANDIN_SWAP_XY
    force[0] = fy; force[1] = fx; force[2] = fz;
#else
    force[0] = fx; force[1] = fy; force[2] = fz;
#endif
    sets++;
    return 0;
}
#endif

/* Test hooks, not part of the vendor API. */
long standin_sets(void) { return sets; }
int standin_force_on(void) { return force_on; }
void standin_force(double *out) { memcpy(out, force, sizeof force); }

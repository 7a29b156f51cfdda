/* A stand-in for the OpenHaptics HD library (libHD.so): the same C functions, a simulated
 * device. Built by the test suite (haptics-server/tests/it/openhaptics.rs) with the `cc`
 * crate; never shipped. The "device" is a stylus on a spring (mass 0.05 kg, hand spring
 * 200 N/m toward the origin) pushed by the commanded force; the scheduler is a pthread that
 * calls the registered callbacks every 1 ms between begin/end frame. Units as the vendor's:
 * positions mm, velocities mm/s, forces N.
 * Compile with -DOMIT_UNSCHEDULE to leave out hdUnschedule (tests of the missing-symbol error).
 */
#include <pthread.h>
#include <stdatomic.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

typedef unsigned int HHD;
typedef unsigned int HDenum;
typedef unsigned int HDerror;
typedef unsigned int HDCallbackCode;
typedef unsigned short HDushort;
typedef unsigned long HDSchedulerHandle;
typedef HDCallbackCode (*HDSchedulerCallback)(void *);
typedef struct { HDerror errorCode; int internalErrorCode; HHD hHD; } HDErrorInfo;

#define HD_INVALID_HANDLE 0xFFFFFFFFu
#define HD_SUCCESS 0x0000
#define HD_COMM_ERROR 0x0201
#define HD_ILLEGAL_BEGIN 0x0204
#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_POSITION 0x2050
#define HD_CURRENT_VELOCITY 0x2051
#define HD_NOMINAL_MAX_STIFFNESS 0x2602
#define HD_NOMINAL_MAX_FORCE 0x2603
#define HD_CURRENT_FORCE 0x2700
#define HD_FORCE_OUTPUT 0x4000
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1

static HDErrorInfo last_error;
static int force_enabled;
static double pos[3], vel[3], force[3], applied[3];
static atomic_long frames;
static atomic_int running;
static pthread_t thread;
static HDSchedulerCallback cb;
static void *cb_data;

HHD hdInitDevice(const char *name) {
    if (name && strcmp(name, "missing") == 0) {
        last_error.errorCode = HD_COMM_ERROR;
        return HD_INVALID_HANDLE;
    }
    memset(pos, 0, sizeof pos);
    memset(vel, 0, sizeof vel);
    return 1;
}
void hdDisableDevice(HHD h) { (void)h; memset(force, 0, sizeof force); memset(applied, 0, sizeof applied); }
void hdMakeCurrentDevice(HHD h) { (void)h; }
HDErrorInfo hdGetError(void) { HDErrorInfo e = last_error; last_error.errorCode = HD_SUCCESS; return e; }
void hdEnable(HDenum cap) { if (cap == HD_FORCE_OUTPUT) force_enabled = 1; }
void hdDisable(HDenum cap) { if (cap == HD_FORCE_OUTPUT) force_enabled = 0; }

void hdBeginFrame(HHD h) {
    (void)h;
    /* 1 ms of stylus dynamics under the force applied last frame. */
    const double dt = 0.001, m = 0.05, k = 200.0, b = 5.0;
    for (int i = 0; i < 3; i++) {
        double x = pos[i] / 1000.0, v = vel[i] / 1000.0;
        double a = (-k * x - b * v + applied[i]) / m;
        v += a * dt;
        x += v * dt;
        pos[i] = x * 1000.0;
        vel[i] = v * 1000.0;
    }
}
void hdEndFrame(HHD h) {
    (void)h;
    for (int i = 0; i < 3; i++) applied[i] = force_enabled ? force[i] : 0.0;
    atomic_fetch_add(&frames, 1);
}

void hdGetDoublev(HDenum p, double *v) {
    switch (p) {
    case HD_CURRENT_POSITION: memcpy(v, pos, sizeof pos); break;
    case HD_CURRENT_VELOCITY: memcpy(v, vel, sizeof vel); break;
    case HD_CURRENT_FORCE: memcpy(v, force, sizeof force); break;
    case HD_NOMINAL_MAX_FORCE: v[0] = 3.3; break;
    case HD_NOMINAL_MAX_STIFFNESS: v[0] = 0.7; break; /* N/mm, as the vendor reports */
    default: last_error.errorCode = 0x0100; break;
    }
}
void hdGetIntegerv(HDenum p, int *v) {
    if (p == HD_CURRENT_BUTTONS) v[0] = 0; else last_error.errorCode = 0x0100;
}
void hdSetDoublev(HDenum p, const double *v) {
    if (p == HD_CURRENT_FORCE) memcpy(force, v, sizeof force); else last_error.errorCode = 0x0100;
}

static void *scheduler(void *arg) {
    (void)arg;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    while (atomic_load(&running)) {
        next.tv_nsec += 1000000;
        if (next.tv_nsec >= 1000000000) { next.tv_nsec -= 1000000000; next.tv_sec++; }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, 0);
        HDSchedulerCallback f = cb;
        if (f && f(cb_data) == HD_CALLBACK_DONE) cb = 0;
    }
    return 0;
}
HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback f, void *data, HDushort prio) {
    (void)prio;
    cb_data = data;
    cb = f;
    return 1;
}
#ifndef OMIT_UNSCHEDULE
void hdUnschedule(HDSchedulerHandle h) { (void)h; cb = 0; }
#endif
void hdStartScheduler(void) {
    if (!atomic_exchange(&running, 1)) pthread_create(&thread, 0, scheduler, 0);
}
void hdStopScheduler(void) {
    if (atomic_exchange(&running, 0)) pthread_join(thread, 0);
}

/* Test hooks, not part of the vendor API. */
long standin_frames(void) { return atomic_load(&frames); }
void standin_force(double *out) { memcpy(out, applied, sizeof applied); }

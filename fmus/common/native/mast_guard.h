/* What the FMI glue of every MAST binary checks before it touches an instance or takes a time: the native FMUs'
 * wrapper (fmi2_wrapper.c) and the Python FMUs' C front (pythonfmu_shim.c) include it, each binary with a
 * registry of its own.
 *
 * - The live instances: the pointers this binary handed out and has not freed. A call with any other pointer
 *   (an instance freed already, one freed twice, a pointer never made here) is refused without reading through
 *   it: a freed instance's memory may belong to anyone by then, so no magic field in it can be trusted. A freed
 *   instance's block waits in a quarantine for MAST_QUARANTINE later frees before it goes back to malloc, so a
 *   new instance does not take at once the address a careless host still holds.
 * - A time argument (a communication point, a step size, a start or stop time): finite and >= 0, else the call
 *   is refused with a message naming the argument and its value (the Python glue words it the same way:
 *   fmus/common/slave.py, ``check_time``).
 */
#ifndef MAST_GUARD_H
#define MAST_GUARD_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>   /* dladdr: the includer defines _GNU_SOURCE first */
#endif

#define MAST_QUARANTINE 16

static void **mast_live_set;
static size_t mast_live_n, mast_live_cap;
static void *mast_quarantine[MAST_QUARANTINE];
static size_t mast_retired;
static char mast_live_busy;

/* a spin lock (no pthread to link): hosts may create and free instances from several threads */
static void mast_live_lock(void)
{
    while (__atomic_test_and_set(&mast_live_busy, __ATOMIC_ACQUIRE)) {
    }
}
static void mast_live_unlock(void) { __atomic_clear(&mast_live_busy, __ATOMIC_RELEASE); }

/* the index of ``p`` among the live instances, or -1 (the lock held) */
static long mast_live_index(const void *p)
{
    for (size_t k = 0; k < mast_live_n; k++)
        if (mast_live_set[k] == p) return (long)k;
    return -1;
}

/* This binary kept loaded until the process exits, so the registry outlives a host's unload: the ecos command
 * line unloads an FMU's library after each fmi2Instantiate and loads it again (at the same address) for the
 * next, its instances alive (measured: a fresh, empty registry each time refused every call of the earlier
 * instances). */
static void mast_pin(void)
{
#ifdef _WIN32
    HMODULE self;
    GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_PIN, (LPCSTR)(void *)&mast_pin,
                       &self);
#else
    Dl_info self;
    if (dladdr((void *)&mast_pin, &self) && self.dli_fname) dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
#endif
}

/* a new instance made live (0: out of memory, the caller frees it) */
static int mast_live_add(void *p)
{
    int ok = 1;
    mast_live_lock();
    if (!mast_live_cap) mast_pin();   /* the first instance */
    if (mast_live_n == mast_live_cap) {
        size_t cap = mast_live_cap ? 2 * mast_live_cap : 16;
        void **grown = realloc(mast_live_set, cap * sizeof *grown);
        if (grown) mast_live_set = grown, mast_live_cap = cap;
        else ok = 0;
    }
    if (ok) mast_live_set[mast_live_n++] = p;
    mast_live_unlock();
    return ok;
}

/* ``p`` if it is a live instance of this binary, else NULL (never read) */
static void *mast_live(void *p)
{
    if (!p) return NULL;
    mast_live_lock();
    long k = mast_live_index(p);
    mast_live_unlock();
    return k < 0 ? NULL : p;
}

/* ``p`` no longer live: 1 if it was (the caller releases what it holds, then mast_retire(p)), 0 if not */
static int mast_live_remove(void *p)
{
    if (!p) return 0;
    mast_live_lock();
    long k = mast_live_index(p);
    if (k >= 0) mast_live_set[k] = mast_live_set[--mast_live_n];
    mast_live_unlock();
    return k >= 0;
}

/* an instance's own block, freed MAST_QUARANTINE frees later (the oldest in the quarantine goes now) */
static void mast_retire(void *p)
{
    mast_live_lock();
    void *oldest = mast_quarantine[mast_retired % MAST_QUARANTINE];
    mast_quarantine[mast_retired++ % MAST_QUARANTINE] = p;
    mast_live_unlock();
    free(oldest);
}

/* at exit (or at the unload of a binary that made no instance: mast_pin): the quarantine and the set released,
 * so a leak checker finds them freed */
__attribute__((destructor)) static void mast_live_release(void)
{
    for (size_t k = 0; k < MAST_QUARANTINE; k++) {
        free(mast_quarantine[k]);
        mast_quarantine[k] = NULL;
    }
    free(mast_live_set);
    mast_live_set = NULL;
    mast_live_n = mast_live_cap = 0;
}

/* a time argument that is not finite and >= 0: the message "<call>: <name> = <value> s: ..." in ``msg`` and 1;
 * else 0. The value as Python's format ".6g" writes it (NaN without a sign, as Python has none for it). */
static int mast_bad_time(const char *call, const char *name, double value, char *msg, size_t size)
{
    char text[32];
    if (isfinite(value) && value >= 0.0) return 0;
    if (isnan(value)) snprintf(text, sizeof text, "nan");
    else snprintf(text, sizeof text, "%.6g", value);
    snprintf(msg, size, "%s: %s = %s s: a time must be finite and >= 0", call, name, text);
    return 1;
}

#endif

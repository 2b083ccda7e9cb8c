/* Support for the generated model files (mast build --native): the scalar functions the generated code
 * calls, inline (they are in the hot kernels), each the same operations as the Python it mirrors, and the
 * text helpers of the messages. The matrix helpers are mast_linalg.h's, the direct kinematics mast_dk.h's.
 */
#ifndef MAST_NATIVE_H
#define MAST_NATIVE_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mast_dk.h"
#include "mast_linalg.h"

static inline double mast_sign(double x) { return x > 0.0 ? 1.0 : -1.0; }   /* engine._sign */
static inline double mast_sgn0(double x) { return x >= 0.0 ? 1.0 : -1.0; }  /* engine._sgn0 */
static inline double mast_hypot(double a, double b) { return hypot(a, b); }

/* x % y of the generated code (tick counters, >= 0): fmod, exact, computed as the integer remainder when
 * both are whole numbers in [0, 2^31) (then the same number: fmod is exact; 0 is +0.0 as fmod's), which
 * costs a few instructions instead of libm's general fmod (a tenth of a controller's step) */
static inline double mast_mod(double x, double y)
{
    if (x >= 0.0 && x < 2147483648.0 && y >= 1.0 && y < 2147483648.0) {
        long a = (long)x, b = (long)y;
        if ((double)a == x && (double)b == y) return (double)(a % b);
    }
    return fmod(x, y);
}

/* Python's repr of a float (shortest round-trip digits, the same layout), for messages */
static inline const char *mast_repr(double x, char *buf, size_t size)
{
    if (isnan(x)) { snprintf(buf, size, "nan"); return buf; }
    if (isinf(x)) { snprintf(buf, size, x > 0 ? "inf" : "-inf"); return buf; }
    char e[40];
    int p;
    for (p = 1; p < 17; p++) {
        snprintf(e, sizeof e, "%.*e", p - 1, x);
        if (strtod(e, NULL) == x) break;
    }
    snprintf(e, sizeof e, "%.*e", p - 1, x);
    int exp10 = atoi(strchr(e, 'e') + 1);
    if (exp10 < -4 || exp10 >= 16) {
        snprintf(buf, size, "%s", e);                      /* Python writes 1e-05, 1.5e+20: as C does */
    } else {
        int decimals = p - 1 - exp10;
        if (decimals < 0) decimals = 0;
        snprintf(buf, size, "%.*f", decimals, x);
        if (!strchr(buf, '.')) strncat(buf, ".0", size - strlen(buf) - 1);
    }
    return buf;
}

/* _parse_list (fmus/actuator/model.py): ``count`` numbers separated by blanks or commas, each finite and
 * > 0 (``positive``) or >= 0, into ``out``. 0; -1 when there are not ``count`` items (*items: how many);
 * k + 1 when item k is not a finite number of that kind (its text in ``item``, ``size`` bytes). */
static inline int mast_parse_list(const char *text, int count, int positive, double *out, int *items, char *item,
                                  size_t size)
{
    const char *blank = " ,\t\n\r\f\v";
    const char *s = text ? text : "";
    int n = 0;
    for (const char *c = s; *c;) {
        c += strspn(c, blank);
        if (!*c) break;
        n++;
        c += strcspn(c, blank);
    }
    *items = n;
    if (n != count) return -1;
    int k = 0;
    for (const char *c = s; *c && k < count; k++) {
        c += strspn(c, blank);
        size_t len = strcspn(c, blank);
        char token[64];
        char *end = NULL;
        double v = NAN;
        if (len < sizeof token) {
            memcpy(token, c, len);
            token[len] = '\0';
            v = strtod(token, &end);
            if (end != token + len) v = NAN;
        }
        if (!isfinite(v) || (positive ? v <= 0.0 : v < 0.0)) {
            snprintf(item, size, "%.*s", (int)len, c);
            return k + 1;
        }
        out[k] = v;
        c += len;
    }
    return 0;
}

#endif

/* The range checks of a model's parameters (mast_ranges.h). */
#include <math.h>
#include <stdio.h>

#include "mast_native.h"
#include "mast_ranges.h"

int mast_check_ranges(const mast_range *ranges, int n, const mast_parameters *p, char *msg, size_t size)
{
    char v[40];
    for (int k = 0; k < n; k++) {
        const mast_range *r = &ranges[k];
        double value = r->integer ? (double)p->integer[r->vr] : p->real[r->vr];
        if (!r->integer && !isfinite(value)) {
            snprintf(msg, size, "parameter '%s' = %s: expected a finite number", r->name, mast_repr(value, v, sizeof v));
            return MAST_PARAMETER_ERROR;
        }
        if (r->exclusive ? value <= r->minimum || value >= r->maximum : value < r->minimum || value > r->maximum) {
            if (r->integer) snprintf(v, sizeof v, "%d", p->integer[r->vr]);
            else mast_repr(value, v, sizeof v);
            snprintf(msg, size, "parameter '%s' = %s: expected %s", r->name, v, r->expected);
            return MAST_PARAMETER_ERROR;
        }
    }
    return MAST_OK;
}

/* The range checks of a model's parameters (mast_ranges.c): the Python model's Param.check, with its
 * messages, from a generated table of one row per Real or Integer parameter. */
#ifndef MAST_RANGES_H
#define MAST_RANGES_H

#include <stddef.h>

#include "mast_model.h"

typedef struct {
    const char *name;
    int vr;                   /* its value reference */
    int integer;              /* 1: an Integer parameter, 0: a Real one (which must also be finite) */
    double minimum, maximum;  /* -INFINITY, INFINITY: no bound */
    int exclusive;            /* the bounds themselves refused */
    const char *expected;     /* Param.expected(): what the message says is expected */
} mast_range;

/* MAST_OK, or MAST_PARAMETER_ERROR with ``msg`` ("parameter 'name' = value: expected ...") for the first of the
 * ``n`` rows whose parameter is out of its range */
int mast_check_ranges(const mast_range *ranges, int n, const mast_parameters *p, char *msg, size_t size);

#endif

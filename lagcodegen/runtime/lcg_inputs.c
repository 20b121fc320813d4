/* lcg_inputs.c -- lagcodegen's runtime: input signals u(t) read from tables (see lcg_inputs.h). */
#include <math.h>
#include <stdio.h>

#include "lcg_inputs.h"

/* The number of the n values x[] <= t (left: < t). */
static int count_below(const double *x, int n, double t, int left)
{
    int lo = 0, hi = n; /* the answer lies in [lo, hi] */

    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (x[mid] < t || (!left && x[mid] == t))
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

int lcg_inputs_check(const lcg_inputs *in, int np, char *message, size_t size)
{
    int a, b, i;

    if (in->count < 0 || (in->count > 0 && in->tables == NULL)) {
        snprintf(message, size, "inputs: %d tables at %p", in->count, (const void *)in->tables);
        return -22;
    }
    if (in->nbreak < 0 || (in->nbreak > 0 && in->breaks == NULL)) {
        snprintf(message, size, "inputs: %d restart times at %p", in->nbreak, (const void *)in->breaks);
        return -22;
    }
    for (i = 0; i < in->nbreak; ++i)
        if (!isfinite(in->breaks[i]) || (i > 0 && !(in->breaks[i] > in->breaks[i - 1]))) {
            snprintf(message, size, "inputs: restart time %d (%g) not finite or not increasing", i, in->breaks[i]);
            return -22;
        }
    for (a = 0; a < in->count; ++a) {
        const lcg_input_table *tab = in->tables + a;
        if (tab->slot < 0 || tab->slot >= np) {
            snprintf(message, size, "input table %d: parameter slot %d out of range (np = %d)", a, tab->slot, np);
            return -22;
        }
        for (b = 0; b < a; ++b)
            if (in->tables[b].slot == tab->slot) {
                snprintf(message, size, "input tables %d and %d both set parameter slot %d", b, a, tab->slot);
                return -22;
            }
        if (tab->n < 1 || tab->t == NULL || tab->c == NULL) {
            snprintf(message, size, "input table %d: %d breakpoints", a, tab->n);
            return -22;
        }
        for (i = 0; i < tab->n; ++i)
            if (!isfinite(tab->t[i]) || (i > 0 && !(tab->t[i] > tab->t[i - 1]))) {
                snprintf(message, size, "input table %d: breakpoint %d (%g) not finite or not increasing", a, i,
                         tab->t[i]);
                return -22;
            }
        for (i = 0; i < 4 * (tab->n + 1); ++i)
            if (!isfinite(tab->c[i])) {
                snprintf(message, size, "input table %d: coefficient %d not finite", a, i);
                return -22;
            }
    }
    return 0;
}

int lcg_input_table_fill(lcg_input_table *tab, int slot, int n, const double *t, const double *v, int kind,
                         double *c)
{
    int k;

    if (n < 1 || (kind != 0 && kind != 1))
        return -22;
    for (k = 1; k < n; ++k)
        if (!(t[k] > t[k - 1]))
            return -22;
    for (k = 0; k < 4 * (n + 1); ++k)
        c[k] = 0.0;
    c[0] = v[0];         /* before t[0]: the first value */
    c[4 * n] = v[n - 1]; /* from t[n-1] on: the last */
    for (k = 1; k < n; ++k) {
        c[4 * k] = v[k - 1];
        if (kind == 1)
            c[4 * k + 1] = (v[k] - v[k - 1]) / (t[k] - t[k - 1]);
    }
    tab->slot = slot;
    tab->n = n;
    tab->t = t;
    tab->c = c;
    return 0;
}

int lcg_input_piece(const lcg_input_table *tab, double t)
{
    return count_below(tab->t, tab->n, t, 0);
}

double lcg_input_value(const lcg_input_table *tab, int k, double t)
{
    const double *c = tab->c + 4 * k;
    double s = t - tab->t[k == 0 ? 0 : k - 1];
    return c[0] + s * (c[1] + s * (c[2] + s * c[3]));
}

void lcg_inputs_apply(const lcg_inputs *in, double t, int left, double *p)
{
    int a;

    for (a = 0; a < in->count; ++a) {
        const lcg_input_table *tab = in->tables + a;
        p[tab->slot] = lcg_input_value(tab, count_below(tab->t, tab->n, t, left), t);
    }
}

double lcg_inputs_next_break(const lcg_inputs *in, double t)
{
    int k = in->nbreak > 0 ? count_below(in->breaks, in->nbreak, t, 0) : 0;
    return k < in->nbreak ? in->breaks[k] : HUGE_VAL;
}

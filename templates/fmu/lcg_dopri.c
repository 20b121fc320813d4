/* lcg_dopri.c -- Dormand-Prince 5(4) with a PI step size controller (see lcg_dopri.h).
 *
 * Coefficients: J. R. Dormand, P. J. Prince, "A family of embedded Runge-Kutta formulae",
 * J. Comp. Appl. Math. 6 (1980) 19-26. The fifth-order solution is propagated (local
 * extrapolation); the last stage is the first of the next step (FSAL) within one call. The
 * controller: h_new = h / clamp(err^(1/5 - 0.75 beta) / err_old^beta / 0.9, 1/10, 5) with
 * beta = 0.04; after a rejection the step does not grow. */
#include <math.h>

#include "lcg_dopri.h"

static const double c2 = 1.0 / 5, c3 = 3.0 / 10, c4 = 4.0 / 5, c5 = 8.0 / 9;
static const double a21 = 1.0 / 5;
static const double a31 = 3.0 / 40, a32 = 9.0 / 40;
static const double a41 = 44.0 / 45, a42 = -56.0 / 15, a43 = 32.0 / 9;
static const double a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561, a54 = -212.0 / 729;
static const double a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247, a64 = 49.0 / 176,
                    a65 = -5103.0 / 18656;
static const double a71 = 35.0 / 384, a73 = 500.0 / 1113, a74 = 125.0 / 192, a75 = -2187.0 / 6784,
                    a76 = 11.0 / 84;
static const double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200,
                    e6 = 22.0 / 525, e7 = -1.0 / 40;

#define SAFE 0.9
#define BETA 0.04
#define FAC_MIN 0.2   /* h_new >= FAC_MIN h */
#define FAC_MAX 10.0  /* h_new <= FAC_MAX h */

void lcg_dopri_init(lcg_dopri *s, int n, double *work, double rtol, double atol)
{
    int j;

    s->n = n;
    s->rtol = rtol;
    s->atol = atol;
    s->h = 0.0;
    s->hmax = 0.0;
    s->facold = 1e-4;
    s->max_steps = 1000000L;
    s->steps = s->rejected = s->evaluations = 0;
    s->rhs_code = 0;
    for (j = 0; j < 7; ++j)
        s->k[j] = work + j * n;
    s->y1 = work + 7 * n;
    s->ysti = work + 8 * n;
}

static double scale(const lcg_dopri *s, double a, double b)
{
    return s->atol + s->rtol * fmax(fabs(a), fabs(b));
}

/* The starting step of Hairer, Norsett and Wanner (sec. II.4): from the sizes of y, f and an
 * estimate of the second derivative. k1 holds f(t, y); uses y1 and k2 as scratch. */
static double starting_step(lcg_dopri *s, lcg_dopri_rhs f, void *data, double t, const double *y,
                            double hmax)
{
    const int n = s->n;
    double d0 = 0.0, d1 = 0.0, d2 = 0.0, h0, h1, der;
    int i;

    for (i = 0; i < n; ++i) {
        const double sk = scale(s, y[i], y[i]);
        d0 += (y[i] / sk) * (y[i] / sk);
        d1 += (s->k[0][i] / sk) * (s->k[0][i] / sk);
    }
    d0 = sqrt(d0 / n);
    d1 = sqrt(d1 / n);
    h0 = (d0 < 1e-10 || d1 < 1e-10) ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, hmax);
    for (i = 0; i < n; ++i)
        s->y1[i] = y[i] + h0 * s->k[0][i];
    s->evaluations++;
    if (f(data, t + h0, s->y1, s->k[1]) != 0)
        return h0 * 1e-3;
    for (i = 0; i < n; ++i) {
        const double sk = scale(s, y[i], y[i]);
        const double d = (s->k[1][i] - s->k[0][i]) / sk;
        d2 += d * d;
    }
    d2 = sqrt(d2 / n) / h0;
    der = fmax(d1, d2);
    h1 = der <= 1e-15 ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / der, 1.0 / 5);
    return fmin(fmin(100 * h0, h1), hmax);
}

int lcg_dopri_advance(lcg_dopri *s, lcg_dopri_rhs f, void *data, double *t, double *y, double t_end)
{
    const int n = s->n;
    double *const k1 = s->k[0], *const k2 = s->k[1], *const k3 = s->k[2], *const k4 = s->k[3];
    double *const k5 = s->k[4], *const k6 = s->k[5], *const k7 = s->k[6];
    double *const y1 = s->y1, *const ysti = s->ysti;
    const double expo1 = 0.2 - BETA * 0.75;
    double hmax = t_end - *t;
    long steps = 0;
    int rejected_last = 0, i, code;

    if (!(hmax > 0.0))
        return LCG_DOPRI_OK;
    if (s->hmax > 0.0 && s->hmax < hmax)
        hmax = s->hmax;
    s->evaluations++;
    code = f(data, *t, y, k1);
    if (code != 0) {
        s->rhs_code = code;
        return LCG_DOPRI_ERR_RHS;
    }
    if (!(s->h > 0.0))
        s->h = starting_step(s, f, data, *t, y, hmax);
    while (*t < t_end) {
        double h = fmin(s->h, hmax), err = 0.0, fac11, fac, hnew;
        int last = 0;

        if (steps >= s->max_steps)
            return LCG_DOPRI_ERR_TOO_MANY_STEPS;
        if (!(h > 8.0 * 2.220446049250313e-16 * fmax(fabs(*t), 1.0)))
            return LCG_DOPRI_ERR_STEP_TOO_SMALL;
        if (*t + 1.01 * h >= t_end) {  /* the last step lands on t_end (no sliver of a step after it) */
            h = t_end - *t;
            last = 1;
        }
        ++steps;
        s->steps++;
        for (i = 0; i < n; ++i)
            y1[i] = y[i] + h * a21 * k1[i];
        code = f(data, *t + c2 * h, y1, k2);
        for (i = 0; code == 0 && i < n; ++i)
            y1[i] = y[i] + h * (a31 * k1[i] + a32 * k2[i]);
        if (code == 0)
            code = f(data, *t + c3 * h, y1, k3);
        for (i = 0; code == 0 && i < n; ++i)
            y1[i] = y[i] + h * (a41 * k1[i] + a42 * k2[i] + a43 * k3[i]);
        if (code == 0)
            code = f(data, *t + c4 * h, y1, k4);
        for (i = 0; code == 0 && i < n; ++i)
            y1[i] = y[i] + h * (a51 * k1[i] + a52 * k2[i] + a53 * k3[i] + a54 * k4[i]);
        if (code == 0)
            code = f(data, *t + c5 * h, y1, k5);
        for (i = 0; code == 0 && i < n; ++i)
            ysti[i] = y[i] + h * (a61 * k1[i] + a62 * k2[i] + a63 * k3[i] + a64 * k4[i] + a65 * k5[i]);
        if (code == 0)
            code = f(data, *t + h, ysti, k6);
        for (i = 0; code == 0 && i < n; ++i)
            y1[i] = y[i] + h * (a71 * k1[i] + a73 * k3[i] + a74 * k4[i] + a75 * k5[i] + a76 * k6[i]);
        if (code == 0)
            code = f(data, *t + h, y1, k7);
        s->evaluations += 6;
        if (code != 0) {  /* f failed inside the step: retry with half the step */
            s->rejected++;
            s->h = 0.5 * h;
            rejected_last = 1;
            continue;
        }
        for (i = 0; i < n; ++i) {
            const double e = h * (e1 * k1[i] + e3 * k3[i] + e4 * k4[i] + e5 * k5[i] + e6 * k6[i] + e7 * k7[i]);
            const double r = e / scale(s, y[i], y1[i]);
            err += r * r;
        }
        err = sqrt(err / n);
        if (!isfinite(err))
            err = 1e10;
        fac11 = pow(err, expo1);
        if (err <= 1.0) {
            fac = fac11 / pow(s->facold, BETA);
            fac = fmax(1.0 / FAC_MAX, fmin(1.0 / FAC_MIN, fac / SAFE));
            hnew = h / fac;
            s->facold = fmax(err, 1e-4);
            if (rejected_last)
                hnew = fmin(hnew, h);
            rejected_last = 0;
            *t = last ? t_end : *t + h;
            for (i = 0; i < n; ++i) {
                y[i] = y1[i];
                k1[i] = k7[i];
            }
            /* a step shortened to land on t_end says nothing against the longer step before it */
            s->h = last ? fmax(hnew, s->h) : hnew;
        } else {
            s->rejected++;
            s->h = h / fmin(1.0 / FAC_MIN, fac11 / SAFE);
            rejected_last = 1;
        }
    }
    return LCG_DOPRI_OK;
}

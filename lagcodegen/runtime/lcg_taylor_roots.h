/* Roots of an event polynomial g(tau) = sum_k g_k tau^k on the step [0, h]: quick exclusion
 * |g_0| > sum_{k>=1} |g_k| h^k, else isolation on s = tau/h in [0, 1] by Descartes' rule of
 * signs with bisection (Vincent-Collins-Akritas), then Brent's method on each isolating
 * interval. Roots of even multiplicity (touching zero without a sign change) are not reported. */

#define TL_DEPTH 48

/* Value of c_0 + c_1 s + ... + c_d s^d. */
static double tl_horner(const double *c, int d, double s)
{
    double v = c[d];
    int k;

    for (k = d - 1; k >= 0; --k)
        v = v * s + c[k];
    return v;
}

/* c(s) -> c(s + 1) in place (Taylor shift by one, d^2/2 additions). */
static void tl_shift1(double *c, int d)
{
    int i, j;

    for (i = 0; i < d; ++i)
        for (j = d - 1; j >= i; --j)
            c[j] += c[j + 1];
}

/* Upper bound of the number of roots of c in (0, 1): the sign variations of the
 * coefficients of (1 + x)^d c(1 / (1 + x)). */
static int tl_descartes(const double *c, int d)
{
    double r[P_MAX + 2];
    int i, n = 0, last = 0;

    for (i = 0; i <= d; ++i)
        r[i] = c[d - i];
    tl_shift1(r, d);
    for (i = 0; i <= d; ++i) {
        int s = r[i] > 0.0 ? 1 : (r[i] < 0.0 ? -1 : 0);
        if (s != 0) {
            if (last != 0 && s != last)
                ++n;
            last = s;
        }
    }
    return n;
}

/* Brent's method on c over [a, b] with c(a) = fa, c(b) = fb of opposite signs. */
static double tl_brent(const double *c, int d, double a, double b, double fa, double fb)
{
    double cc = a, fc = fa, e = b - a, dd = e;
    int it;

    for (it = 0; it < 200; ++it) {
        double tol, m, p, q, r, s;
        if ((fb > 0.0) == (fc > 0.0)) {
            cc = a;
            fc = fa;
            e = dd = b - a;
        }
        if (fabs(fc) < fabs(fb)) {
            a = b;
            b = cc;
            cc = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        tol = 2.0 * DBL_EPSILON * fabs(b) + 0.5 * DBL_MIN;
        m = 0.5 * (cc - b);
        if (fabs(m) <= tol || fb == 0.0)
            return b;
        if (fabs(e) >= tol && fabs(fa) > fabs(fb)) {
            s = fb / fa;
            if (a == cc) {
                p = 2.0 * m * s;
                q = 1.0 - s;
            } else {
                q = fa / fc;
                r = fb / fc;
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0));
                q = (q - 1.0) * (r - 1.0) * (s - 1.0);
            }
            if (p > 0.0)
                q = -q;
            else
                p = -p;
            if (2.0 * p < 3.0 * m * q - fabs(tol * q) && p < fabs(0.5 * e * q)) {
                e = dd;
                dd = p / q;
            } else {
                dd = m;
                e = m;
            }
        } else {
            dd = m;
            e = m;
        }
        a = b;
        fa = fb;
        b += fabs(dd) > tol ? dd : (m > 0.0 ? tol : -tol);
        fb = tl_horner(c, d, b);
    }
    return b;
}

/* Roots of g (degree d) in (0, h] with their crossing directions, increasing; returns how
 * many (at most max). */
static int tl_roots(const double *g, int d, double h, double *tau, int *dir, int max)
{
    double c[P_MAX + 2], stack[TL_DEPTH + 2][P_MAX + 2], lo[TL_DEPTH + 2], width[TL_DEPTH + 2];
    double bound = 0.0, hk = h;
    int depth[TL_DEPTH + 2];
    int k, top = 0, n = 0;

    for (k = 1; k <= d; ++k) {
        bound += fabs(g[k]) * hk;
        hk *= h;
    }
    if (fabs(g[0]) > bound)
        return 0; /* |g(tau) - g_0| <= bound < |g_0|: no root on [0, h] */
    memset(c, 0, sizeof c);
    hk = 1.0;
    for (k = 0; k <= d; ++k) {
        c[k] = g[k] * hk;
        hk *= h;
    }
    if (tl_horner(c, d, 1.0) == 0.0 && n < max) { /* a root exactly at the end of the step */
        tau[n] = h;
        dir[n++] = tl_horner(c, d, 1.0 - 1e-9) < 0.0 ? 1 : -1;
    }
    for (k = 0; k <= d; ++k)
        stack[0][k] = c[k];
    lo[0] = 0.0;
    width[0] = 1.0;
    depth[0] = 0;
    top = 1;
    while (top > 0 && n < max) {
        double *q = stack[--top];
        double a = lo[top], w = width[top];
        int v = tl_descartes(q, d), lv = depth[top];
        if (v == 0)
            continue;
        if (v == 1 || lv >= TL_DEPTH) {
            double fa = tl_horner(c, d, a), fb = tl_horner(c, d, a + w);
            if (fa != 0.0 && fb != 0.0 && (fa > 0.0) != (fb > 0.0)) {
                double s = tl_brent(c, d, a, a + w, fa, fb);
                tau[n] = s * h;
                dir[n++] = fb > 0.0 ? 1 : -1;
            }
            continue;
        }
        /* Bisect: left half q(x/2), right half q((x + 1)/2), the right one explored last. */
        {
            double *left = stack[top], *right = stack[top + 1], scale = 1.0, mid;
            for (k = 0; k <= d; ++k) {
                left[k] = q[k] * scale;
                scale *= 0.5;
            }
            for (k = 0; k <= d; ++k)
                right[k] = left[k];
            tl_shift1(right, d);
            mid = a + 0.5 * w;
            if (right[0] == 0.0 && n < max) { /* a root exactly at the midpoint */
                tau[n] = mid * h;
                dir[n++] = tl_horner(c, d, a + w) > 0.0 ? 1 : -1;
            }
            /* push right first (explored last): swap the two buffers' roles */
            for (k = 0; k <= d; ++k) {
                double tmp = left[k];
                left[k] = right[k];
                right[k] = tmp;
            }
            lo[top] = mid;
            width[top] = 0.5 * w;
            depth[top] = lv + 1;
            lo[top + 1] = a;
            width[top + 1] = 0.5 * w;
            depth[top + 1] = lv + 1;
            top += 2;
        }
    }
    /* increasing order (isolation visits intervals left to right, the end points may not be) */
    for (k = 1; k < n; ++k) {
        double t = tau[k];
        int dr = dir[k], j = k - 1;
        while (j >= 0 && tau[j] > t) {
            tau[j + 1] = tau[j];
            dir[j + 1] = dir[j];
            --j;
        }
        tau[j + 1] = t;
        dir[j + 1] = dr;
    }
    return n;
}

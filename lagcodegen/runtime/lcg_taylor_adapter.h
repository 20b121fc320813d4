/* lcg_taylor_adapter.h -- lagcodegen's runtime: the model-table form of the Taylor driver's
 * sizes and functions (lcg_taylor_driver.h), for the runtime's translation units that include the
 * driver on a jet's table m (lcg_taylor.c; the Taylor contact driver lcg_taylor_imp.c on its
 * contact jet's table), and the check of such a table. Include before lcg_taylor_driver.h, with
 * lcg_taylor_model.h included. */
#ifndef LCG_TAYLOR_ADAPTER_H
#define LCG_TAYLOR_ADAPTER_H

/* The driver's runtime-only parts (lcg_taylor_driver.h): the table check, tolerances by blocks. */
#define LCG_TAYLOR_RUNTIME 1

/* The sizes and functions of the model m (the driver's argument) for the driver (lcg_taylor_driver.h). */
#define NY (m->ny)
#define NE (m->ne)
#define NOUT (m->nout)
#define NROW (m->nrows)
#define P_MAX LCG_TAYLOR_ORDER_MAX
#define PS (P_MAX + 2)
#define TL_WORK_SIZE (m->work_size)
#define TL_START(work, p) m->start(work, p)
#define TL_JET(work, X, t, y, kmax) m->jet(work, X, t, y, kmax)
#define TL_OUTPUTS(t, y, p, out) (m->outputs != NULL ? m->outputs(t, y, p, out) : 0)
#define TL_EVENT_ROW(e) (m->event_row[e])
#define TL_EVENT_DIRECTION(e) (m->event_direction[e])
#define TL_EVENT_TERMINAL(e) (m->event_terminal[e])

/* A table this driver can use: its version and order limit, consistent sizes. */
static int tl_table_ok(const lcg_taylor_model *m)
{
    return m != NULL && m->abi == LCG_TAYLOR_ABI && m->order_max == LCG_TAYLOR_ORDER_MAX && m->nq >= 0
        && m->nz >= 0 && m->ny == 2 * m->nq + m->nz && m->ny > 0 && m->nrows >= m->ny + m->nq && m->nout >= 0
        && m->ne >= 0 && m->start != NULL && m->jet != NULL && (m->nout == 0 || m->outputs != NULL)
        && (m->ne == 0 || (m->event_row != NULL && m->event_direction != NULL && m->event_terminal != NULL));
}

#endif /* LCG_TAYLOR_ADAPTER_H */

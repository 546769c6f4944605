/* fluid_state.c - the fluid's checkpoint: everything a step reads that an earlier step wrote.
 *
 * Particles are saved in their memory order (the order of every sum over them). The
 * neighbour lists are not saved: they are a function of the positions at their last rebuild
 * (grid.h), so those positions are saved and the lists rebuilt from them on load, which
 * gives the same candidates in the same order; the resumed run then rebuilds and re-sorts
 * exactly when the uninterrupted one does. Scratch arrays that every step recomputes
 * before reading (dx, hit, D, the spring gains) are left out. */
#include "state.h"

#include "cy.h"
#include "fluid.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define F64 STF_STATE_F64
#define F32 STF_STATE_F32
#define I32 STF_STATE_I32
#define I64 STF_STATE_I64

static int save_springs(const stf_springs *sp, int n, stf_state *s)
{
    /* rows packed one after the other (CSR), in each row's order */
    long total = 0; /* slots: each spring is on both of its particles */
    for (int i = 0; i < n; i++) total += sp->count[i];
    int32_t *partner = malloc((size_t)(total > 0 ? total : 1) * sizeof *partner);
    double *rest = malloc((size_t)(total > 0 ? total : 1) * sizeof *rest);
    if (!partner || !rest) {
        free(partner);
        free(rest);
        return -1;
    }
    size_t k = 0;
    for (int i = 0; i < n; i++) {
        size_t row = (size_t)i * (size_t)sp->stride, c = (size_t)sp->count[i];
        memcpy(partner + k, sp->partner + row, c * sizeof *partner);
        memcpy(rest + k, sp->rest + row, c * sizeof *rest);
        k += c;
    }
    stf_state_put(s, "springs.count", I32, (size_t)n, sp->count);
    stf_state_put_owned(s, "springs.partner", I32, (size_t)total, partner);
    stf_state_put_owned(s, "springs.rest", F64, (size_t)total, rest);
    stf_state_put_i64(s, "springs.stride", sp->stride);
    stf_state_put_i64(s, "springs.saturated_steps", sp->saturated_steps);
    stf_state_put_f64(s, "springs.max_gain", sp->max_gain);
    return 0;
}

static int save_history(const stf_history *h, int n, stf_state *s)
{
    stf_state_put_i64(s, "history.pushed", h->pushed);
    if (h->terms) {
        stf_state_put_i64(s, "history.terms", h->terms);
        stf_state_put(s, "history.soe_T", F64, (size_t)n * (size_t)h->terms * 3, h->soe_T);
        stf_state_put(s, "history.soe_v0", F64, (size_t)n * 3, h->soe_v0);
        return 0;
    }
    stf_state_put_i64(s, "history.window", h->window);
    stf_state_put_i64(s, "history.cap", h->cap);
    stf_state_put_i64(s, "history.head", h->head);
    /* the ring as it is, rows and their particles (a copy in particle order would cost the
       half-gigabyte ring of the bowling ball twice, while an interrupted run waits) */
    stf_state_put_i64(s, "history.rows", h->rows);
    stf_state_put(s, "history.part", I32, (size_t)h->rows, h->part);
    stf_state_put_rows(s, "history.ring", F32, (size_t)h->cap, 3 * (size_t)h->rows,
                       3 * (size_t)h->n_alloc, h->ring);
    return 0;
}

int stf_fluid_save_state(const stf_fluid *f, stf_state *s)
{
    int n = f->n;
    stf_state_put_i64(s, "fluid.n", n);
    stf_state_put_i64(s, "fluid.next_id", f->next_id);
    stf_state_put_i64(s, "fluid.steps", f->steps);
    stf_state_put_i64(s, "fluid.next_reorder", f->next_reorder);
    stf_state_put_f64(s, "fluid.time", f->time);
    stf_state_put_f64(s, "fluid.dt_now", f->dt_now);
    stf_state_put(s, "fluid.x", F64, 3 * (size_t)n, f->x);
    stf_state_put(s, "fluid.v", F64, 3 * (size_t)n, f->v);
    stf_state_put(s, "fluid.xprev", F64, 3 * (size_t)n, f->xprev);
    stf_state_put(s, "fluid.id", I32, (size_t)n, f->id);
    if (f->khist_mean) stf_state_put(s, "fluid.khist_mean", F32, (size_t)n, f->khist_mean);
    /* springs.passive: the last step's history derivative, the next step's "before" */
    if (f->Dprev && f->Dprev_ok) stf_state_put(s, "fluid.Dprev", F64, 3 * (size_t)n, f->Dprev);
    if (f->rho) {
        stf_state_put(s, "fluid.rho", F64, (size_t)n, f->rho);
        stf_state_put(s, "fluid.rho_near", F64, (size_t)n, f->rho_near);
    }
    const stf_grid *g = &f->grid;
    stf_state_put_i64(s, "grid.valid", g->valid && g->xref);
    stf_state_put_f64(s, "grid.skin", g->skin);
    if (g->valid && g->xref) {
        stf_state_put(s, "grid.xref", F64, 3 * (size_t)g->nref, g->xref);
        stf_state_put_f64(s, "grid.href", g->href);
        stf_state_put_f64(s, "grid.skin_used", g->skin_used);
    }
    if (f->springs.n_alloc && save_springs(&f->springs, n, s) != 0) return -1;
    stf_state_put_i64(s, "history.started", f->hist.w != NULL);
    if (f->hist.w && save_history(&f->hist, n, s) != 0) return -1;
    if (f->cy && stf_cy_save_state(f, s) != 0) return -1;
    return s->failed ? -1 : 0;
}

static int load_springs(stf_fluid *f, const stf_state *s, char *err, size_t errlen)
{
    stf_springs *sp = &f->springs;
    int n = f->n;
    int64_t stride, sat;
    if (stf_state_get_i64(s, "springs.stride", &stride, err, errlen) ||
        stf_state_get_i64(s, "springs.saturated_steps", &sat, err, errlen) ||
        stf_state_get_f64(s, "springs.max_gain", &sp->max_gain, err, errlen) ||
        stf_state_get(s, "springs.count", I32, (size_t)n, sp->count, err, errlen))
        return -1;
    long total = 0;
    for (int i = 0; i < n; i++) {
        if (sp->count[i] < 0 || sp->count[i] > stride) {
            snprintf(err, errlen, "checkpoint: springs.count[%d] out of range", i);
            return -1;
        }
        total += sp->count[i];
    }
    const stf_state_entry *p = stf_state_find(s, "springs.partner", I32, (size_t)total);
    const stf_state_entry *r = stf_state_find(s, "springs.rest", F64, (size_t)total);
    if (!p || !r) {
        snprintf(err, errlen, "checkpoint: springs.partner/rest missing or not %ld long", total);
        return -1;
    }
    if (stride > 1 << 20 || stf_springs_reserve_stride(sp, n, (int)stride) != 0) {
        snprintf(err, errlen, "checkpoint: cannot hold springs.stride = %ld", (long)stride);
        return -1;
    }
    sp->saturated_steps = (long)sat;
    memset(sp->complete, 0, (size_t)n * sizeof *sp->complete); /* search again (springs.c) */
    const int32_t *pp = p->data;
    const double *rr = r->data;
    size_t k = 0;
    for (int i = 0; i < n; i++) {
        size_t row = (size_t)i * (size_t)sp->stride, c = (size_t)sp->count[i];
        for (size_t m = 0; m < c; m++)
            if (pp[k + m] < 0 || pp[k + m] >= n) {
                snprintf(err, errlen, "checkpoint: springs.partner out of range");
                return -1;
            }
        memcpy(sp->partner + row, pp + k, c * sizeof *pp);
        memcpy(sp->rest + row, rr + k, c * sizeof *rr);
        k += c;
    }
    return 0;
}

static int load_history(stf_fluid *f, const stf_state *s, char *err, size_t errlen)
{
    stf_history *h = &f->hist;
    int n = f->n, cap_n = f->cap > 0 ? f->cap : 1;
    int64_t pushed;
    if (stf_state_get_i64(s, "history.pushed", &pushed, err, errlen)) return -1;
    if (h->n_alloc || h->w) stf_history_free(h);
    if (f->def.history_mode == STF_HISTORY_SOE) {
        if (stf_history_soe_init(h, f->def.q, f->def.terms, cap_n) != 0) goto oom;
        h->pushed = (long)pushed;
        return stf_state_get(s, "history.soe_T", F64, (size_t)n * (size_t)h->terms * 3, h->soe_T,
                             err, errlen) ||
                       stf_state_get(s, "history.soe_v0", F64, (size_t)n * 3, h->soe_v0, err, errlen)
                   ? -1 : 0;
    }
    int64_t window, cap, head;
    if (stf_state_get_i64(s, "history.window", &window, err, errlen) ||
        stf_state_get_i64(s, "history.cap", &cap, err, errlen) ||
        stf_state_get_i64(s, "history.head", &head, err, errlen))
        return -1;
    if (window < 0 || cap < 1 || cap > 1 << 24 || head < -1 || head >= cap ||
        (window > 0 && cap != window + 1) || (window == 0) != (f->def.history_mode == STF_HISTORY_FULL)) {
        snprintf(err, errlen, "checkpoint: history window %ld / slots %ld / head %ld do not fit "
                 "the scene", (long)window, (long)cap, (long)head);
        return -1;
    }
    if (stf_history_init(h, f->def.q, (int)window, cap_n) != 0 || stf_history_set_slots(h, (int)cap) != 0)
        goto oom;
    h->pushed = (long)pushed;
    h->head = (int)head;
    int64_t rows;
    if (stf_state_get_i64(s, "history.rows", &rows, err, errlen)) return -1;
    if (rows < n || rows > (int64_t)n + (1 << 24)) {
        snprintf(err, errlen, "checkpoint: %ld history rows for %d particles", (long)rows, n);
        return -1;
    }
    size_t row = (size_t)rows * 3;
    const stf_state_entry *ring = stf_state_find(s, "history.ring", F32, (size_t)cap * row);
    const stf_state_entry *part = stf_state_find(s, "history.part", I32, (size_t)rows);
    if (!ring || !part) {
        snprintf(err, errlen, "checkpoint: history.%s is missing or has the wrong type or size",
                 ring ? "part" : "ring");
        return -1;
    }
    int rc = 0;
    if (stf_history_ring_set(h, ring->data, (int)rows, part->data, n) != 0) {
        snprintf(err, errlen, "checkpoint: the history ring's rows do not name its %ld "
                 "particles once each (or out of memory)", (long)rows);
        rc = -1;
    }
    return rc;
oom:
    snprintf(err, errlen, "checkpoint: out of memory for the history");
    return -1;
}

int stf_fluid_load_state(stf_fluid *f, const stf_state *s, char *err, size_t errlen)
{
    int64_t n, next_id, steps, next_reorder, valid, started;
    if (stf_state_get_i64(s, "fluid.n", &n, err, errlen)) return -1;
    if (n != f->n) {
        snprintf(err, errlen, "checkpoint: %ld particles, the scene makes %d", (long)n, f->n);
        return -1;
    }
    size_t N = (size_t)n;
    if (stf_state_get_i64(s, "fluid.next_id", &next_id, err, errlen) ||
        stf_state_get_i64(s, "fluid.steps", &steps, err, errlen) ||
        stf_state_get_i64(s, "fluid.next_reorder", &next_reorder, err, errlen) ||
        stf_state_get_f64(s, "fluid.time", &f->time, err, errlen) ||
        stf_state_get_f64(s, "fluid.dt_now", &f->dt_now, err, errlen) ||
        stf_state_get(s, "fluid.x", F64, 3 * N, f->x, err, errlen) ||
        stf_state_get(s, "fluid.v", F64, 3 * N, f->v, err, errlen) ||
        stf_state_get(s, "fluid.xprev", F64, 3 * N, f->xprev, err, errlen) ||
        stf_state_get(s, "fluid.id", I32, N, f->id, err, errlen) ||
        (f->khist_mean && stf_state_get(s, "fluid.khist_mean", F32, N, f->khist_mean, err, errlen)) ||
        (f->rho && (stf_state_get(s, "fluid.rho", F64, N, f->rho, err, errlen) ||
                    stf_state_get(s, "fluid.rho_near", F64, N, f->rho_near, err, errlen))) ||
        stf_state_get_i64(s, "grid.valid", &valid, err, errlen) ||
        stf_state_get_f64(s, "grid.skin", &f->grid.skin, err, errlen) ||
        stf_state_get_i64(s, "history.started", &started, err, errlen))
        return -1;
    /* springs.passive: the last step's D, when the run had taken one with history */
    f->Dprev_ok = 0;
    if (f->Dprev && stf_state_find(s, "fluid.Dprev", F64, 3 * N)) {
        if (stf_state_get(s, "fluid.Dprev", F64, 3 * N, f->Dprev, err, errlen)) return -1;
        f->Dprev_ok = 1;
    }
    f->next_id = (int)next_id;
    f->steps = (long)steps;
    f->next_reorder = (long)next_reorder;
    for (size_t i = 0; i < N; i++)
        if (f->id[i] < 0 || f->id[i] >= f->next_id) {
            snprintf(err, errlen, "checkpoint: particle id out of range");
            return -1;
        }
    /* a damaged file: a step saved is a good step, so its state is finite (resumed, it would
       end as a numerical failure, which is not resumable) */
    const char *vec[3] = {"fluid.x", "fluid.v", "fluid.xprev"};
    const double *arr[3] = {f->x, f->v, f->xprev};
    for (int k = 0; k < 3; k++)
        for (size_t i = 0; i < 3 * N; i++)
            if (!isfinite(arr[k][i])) {
                snprintf(err, errlen, "checkpoint: %s[%zu] is not finite", vec[k], i);
                return -1;
            }
    grid_invalidate(&f->grid);
    if (valid) {
        double href, skin_used;
        const stf_state_entry *xr = stf_state_find(s, "grid.xref", F64, 3 * N);
        if (!xr) {
            snprintf(err, errlen, "checkpoint: grid.xref missing or not 3 n long");
            return -1;
        }
        if (stf_state_get_f64(s, "grid.href", &href, err, errlen) ||
            stf_state_get_f64(s, "grid.skin_used", &skin_used, err, errlen))
            return -1;
        if (stf_grid_restore(&f->grid, xr->data, (int)n, href, skin_used) != 0) {
            snprintf(err, errlen, "checkpoint: out of memory for the neighbour lists");
            return -1;
        }
    }
    if (f->springs.n_alloc && load_springs(f, s, err, errlen) != 0) return -1;
    if (has(f, STF_EFFECT_HISTORY) && started && load_history(f, s, err, errlen) != 0) return -1;
    if (f->cy && stf_cy_load_state(f, s, err, errlen) != 0) return -1;
    return 0;
}

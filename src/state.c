/* state.c - named arrays of a checkpoint (see state.h). */
#include "state.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

size_t stf_state_type_size(int type)
{
    return type == STF_STATE_F64 || type == STF_STATE_I64 ? 8 : 4;
}

static stf_state_entry *add(stf_state *s, const char *name)
{
    if (strlen(name) >= sizeof s->e[0].name) return s->failed = 1, NULL;
    if (s->n == s->cap) {
        int cap = s->cap ? 2 * s->cap : 32;
        stf_state_entry *e = realloc(s->e, (size_t)cap * sizeof *e);
        if (!e) return s->failed = 1, NULL;
        s->e = e;
        s->cap = cap;
    }
    stf_state_entry *e = &s->e[s->n++];
    memset(e, 0, sizeof *e);
    strcpy(e->name, name);
    return e;
}

void stf_state_put(stf_state *s, const char *name, int type, size_t count, const void *data)
{
    stf_state_entry *e = add(s, name);
    if (!e) return;
    e->type = type;
    e->count = count;
    e->data = data;
}

void stf_state_put_rows(stf_state *s, const char *name, int type, size_t rows, size_t len,
                        size_t stride, const void *data)
{
    int before = s->n;
    stf_state_put(s, name, type, rows * len, data);
    if (s->n > before) s->e[before].rows = rows, s->e[before].stride = stride;
}

void stf_state_put_owned(stf_state *s, const char *name, int type, size_t count, void *data)
{
    stf_state_entry *e = data ? add(s, name) : NULL;
    if (!e) {
        free(data);
        s->failed = 1;
        return;
    }
    e->type = type;
    e->count = count;
    e->data = e->owned = data;
}

void stf_state_put_f64(stf_state *s, const char *name, double v)
{
    double *p = malloc(sizeof *p);
    if (p) *p = v;
    stf_state_put_owned(s, name, STF_STATE_F64, 1, p);
}

void stf_state_put_i64(stf_state *s, const char *name, int64_t v)
{
    int64_t *p = malloc(sizeof *p);
    if (p) *p = v;
    stf_state_put_owned(s, name, STF_STATE_I64, 1, p);
}

const stf_state_entry *stf_state_find(const stf_state *s, const char *name, int type, size_t want)
{
    for (int k = 0; k < s->n; k++)
        if (!strcmp(s->e[k].name, name))
            return s->e[k].type == type && (want == (size_t)-1 || s->e[k].count == want) ? &s->e[k]
                                                                                       : NULL;
    return NULL;
}

int stf_state_get(const stf_state *s, const char *name, int type, size_t count, void *dst,
                  char *err, size_t errlen)
{
    const stf_state_entry *e = stf_state_find(s, name, type, count);
    if (!e) {
        snprintf(err, errlen, "checkpoint: %s is missing or has the wrong type or size (want %zu)",
                 name, count);
        return -1;
    }
    if (count) memcpy(dst, e->data, count * stf_state_type_size(type));
    return 0;
}

int stf_state_get_f64(const stf_state *s, const char *name, double *v, char *err, size_t errlen)
{
    return stf_state_get(s, name, STF_STATE_F64, 1, v, err, errlen);
}

int stf_state_get_i64(const stf_state *s, const char *name, int64_t *v, char *err, size_t errlen)
{
    return stf_state_get(s, name, STF_STATE_I64, 1, v, err, errlen);
}

void stf_state_free(stf_state *s)
{
    for (int k = 0; k < s->n; k++) free(s->e[k].owned);
    free(s->e);
    memset(s, 0, sizeof *s);
}

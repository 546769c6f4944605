/* state.h - internal: a run's state as named arrays, for checkpoints (`stf run --resume`).
 *
 * The fluid, the ODE side and the run loop each put what they need to continue bit for bit
 * (stf_fluid_save_state, stf_sim_save_state, tools/run.c); h5io.c writes the record as one
 * dataset per entry under /checkpoint and reads it back. Saving borrows the arrays (they
 * must live until the record is written); a record read from a file owns its arrays. */
#ifndef STF_STATE_H
#define STF_STATE_H

#include <stddef.h>
#include <stdint.h>

enum stf_state_type { STF_STATE_F64, STF_STATE_F32, STF_STATE_I32, STF_STATE_I64 };

typedef struct stf_state_entry {
    char name[48];
    int type;       /* stf_state_type */
    size_t count;   /* elements */
    const void *data;
    /* rows > 0: data holds count / rows elements at each of rows row starts, stride
       elements apart (a part of a wider array, written without a copy); 0: contiguous */
    size_t rows, stride;
    void *owned;    /* data when the record owns it (read from a file), else NULL */
} stf_state_entry;

typedef struct stf_state {
    int n, cap;
    stf_state_entry *e;
    int failed; /* a put ran out of memory */
} stf_state;

size_t stf_state_type_size(int type);
/* Adds an entry borrowing data (count elements of type). Marks the record failed when out
 * of memory or the name is too long. */
void stf_state_put(stf_state *s, const char *name, int type, size_t count, const void *data);
/* Adds an entry borrowing rows runs of len elements, their starts stride elements apart in
 * data (stride >= len); stored as one array of rows * len elements. */
void stf_state_put_rows(stf_state *s, const char *name, int type, size_t rows, size_t len,
                        size_t stride, const void *data);
/* Adds an entry that takes ownership of data (malloc'ed). */
void stf_state_put_owned(stf_state *s, const char *name, int type, size_t count, void *data);
void stf_state_put_f64(stf_state *s, const char *name, double v);   /* copies the value */
void stf_state_put_i64(stf_state *s, const char *name, int64_t v);  /* copies the value */
/* The entry name with this type, or NULL (also when count differs from want, unless want
 * is (size_t)-1). */
const stf_state_entry *stf_state_find(const stf_state *s, const char *name, int type, size_t want);
/* Copies entry name into dst (count elements). 0, or -1 with "checkpoint: NAME ..." in err. */
int stf_state_get(const stf_state *s, const char *name, int type, size_t count, void *dst,
                  char *err, size_t errlen);
int stf_state_get_f64(const stf_state *s, const char *name, double *v, char *err, size_t errlen);
int stf_state_get_i64(const stf_state *s, const char *name, int64_t *v, char *err, size_t errlen);
void stf_state_free(stf_state *s);

/* The fluid's state (fluid_state.c): particles in memory order, springs, history, the
 * neighbour lists' reference, counters; the Carreau-Yasuda warm start (cy.c). Load into a
 * fluid freshly built from the same scene. 0, or -1 with a message. */
struct stf_fluid;
int stf_fluid_save_state(const struct stf_fluid *f, stf_state *s);
int stf_fluid_load_state(struct stf_fluid *f, const stf_state *s, char *err, size_t errlen);

#endif

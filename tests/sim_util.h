/* sim_util.h - for the C tests that build a simulation from scene text (include after
 * test_util.h and stf_sim.h). */
#ifndef STF_SIM_UTIL_H
#define STF_SIM_UTIL_H

/* The scene text loaded as file name and made real; NULL (a failed CHECK) when either step
 * fails, *sc then freed and NULL. Free with stf_sim_destroy and stf_scene_free. */
static stf_sim *load_sim(const char *name, const char *text, stf_scene **sc)
{
    char err[1024];
    stf_sim *s = NULL;
    *sc = NULL;
    CHECK(stf_scene_load_string(name, text, NULL, 0, sc, err, sizeof err) == 0, "%s", err);
    if (*sc) CHECK(stf_sim_create(*sc, &s, err, sizeof err) == 0, "%s", err);
    if (!s) {
        stf_scene_free(*sc);
        *sc = NULL;
    }
    return s;
}
#endif

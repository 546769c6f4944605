/* A minimal outside user of libstf_io: a scene given as text is loaded and checked.
 * Exits 0 when the scene's values arrived and a bad key was refused by name. */
#include <stdio.h>
#include <string.h>
#include <stf_io.h>

int main(void)
{
    const char *text = "name: outside\nduration: 0.1\ndt: 0.001\nframe_rate: 30\n"
                       "fluid:\n  spacing: 0.02\n  blocks:\n    - min: [0, 0, 0]\n"
                       "      max: [0.1, 0.1, 0.1]\neffects:\n  gravity: {}\n";
    char err[512];
    stf_scene *s;
    if (stf_scene_load_string("outside.yaml", text, NULL, 0, &s, err, sizeof err))
        return fprintf(stderr, "%s\n", err), 1;
    int ok = s->nblocks == 1 && s->fluid.spacing == 0.02 && s->duration == 0.1;
    stf_scene_free(s);
    stf_override bad = {"fluid.spacing", "-1"};
    if (stf_scene_load_string("outside.yaml", text, &bad, 1, &s, err, sizeof err) != 2 ||
        !strstr(err, "spacing"))
        return fprintf(stderr, "a negative spacing was not refused by name: %s\n", err), 1;
    if (!ok) return fprintf(stderr, "scene values did not arrive\n"), 1;
    printf("outside (stf_io): ok\n");
    return 0;
}

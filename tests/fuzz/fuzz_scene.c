/* fuzz_scene.c - libFuzzer harness for the scene parser: any bytes, as a scene file and with
 * an override, must give 0 or 2 and a message, never a crash or a sanitizer report. */
#include <stdlib.h>
#include <string.h>

#include "stf_io.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = 0;
    char err[1024];
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("fuzz.yaml", text, NULL, 0, &s, err, sizeof err);
    if (rc == 0) stf_scene_free(s);
    else if (rc != 2 || err[0] == 0) abort(); /* bad input must be reported as such */
    stf_override ov[2] = {{"effects.history.q", "0.3"}, {"bodies.0", NULL}};
    rc = stf_scene_load_string("fuzz.yaml", text, ov, 2, &s, err, sizeof err);
    if (rc == 0) stf_scene_free(s);
    else if (rc != 2 || err[0] == 0) abort();
    free(text);
    return 0;
}

/*
 * avatar_render — weft's avatar performs a motion wearing a garment, rendered off-screen.
 *
 *   avatar_render --motion walk --garment tshirt --frames 120 --out frames/
 *   avatar_render --motion bvh:/usr/share/assimp/models/BVH/01_01.bvh --garment dress
 *
 * The cloth is stepped through the public garment API with the best method the build has;
 * frames go to --out as PNGs with a contact sheet, and per-frame timing is printed. The same
 * program is `weft render`.
 */
#include "weft_sample.h"

int main(int argc, char **argv)
{
    weft_avatar_sample_options options;
    weft_avatar_sample_default_options(&options);
    int parsed = weft_avatar_sample_parse("avatar_render", argc, argv, &options);
    if (parsed == 1) {
        weft_avatar_sample_usage(stdout, "avatar_render");
        return 0;
    }
    if (parsed != 0) {
        return 2;
    }
    return weft_avatar_sample_run(&options);
}

/* Skinning baseline (WEFT_METHOD_LBS): the garment bound to the collider at creation by the skin
 * binding of geometry.h, and carried by it every frame. A garment with its own binding (tethers,
 * cuts; made from the same initial state) lends it, and the tethers then take this step's skin. */
#include "xpbd/xpbd.h"

#include <string.h>

static weft_result lbs_create(weft_garment *g)
{
    if (g->skin) {
        g->method_state = g->skin;
        return WEFT_OK;
    }
    geo_skin *s = NULL;
    weft_result r = weft__garment_skin_create(g, "lbs (the skinning baseline)", &s);
    if (r == WEFT_OK) {
        g->method_state = s;
    }
    return r;
}

/* An instance steps through its asset's binding (constant, with its evaluation scratch). */
static weft_result lbs_instance(const weft_garment *proto, weft_garment *g)
{
    g->method_state = proto->method_state;
    return WEFT_OK;
}

static void lbs_destroy(weft_garment *g)
{
    if (!g->asset && g->method_state != g->skin) {
        geo_skin_destroy(g->ctx, g->method_state);
    }
    g->method_state = NULL;
}

static weft_result lbs_step(weft_garment *g)
{
    if (g->method_state != g->skin || !g->tether_target) {
        return geo_skin_eval(g->method_state, g->collider_triangles, g->collider_next, "lbs", g->x_next);
    }
    weft_result r = geo_skin_eval(g->skin, g->collider_triangles, g->collider_next, "lbs", g->tether_target);
    if (r == WEFT_OK) {
        memcpy(g->x_next, g->tether_target, (size_t)g->vertex_count * 3 * sizeof(float));
        g->skinned_next = g->tether_target;
    }
    return r;
}

const weft_method_ops weft__lbs_ops = {
    .name = "lbs",
    .supports_pins = false,
    .create = lbs_create,
    .destroy = lbs_destroy,
    .instance = lbs_instance,
    .reset = NULL,
    .step = lbs_step,
};

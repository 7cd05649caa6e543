#include "garment/garment.h"
#include "xpbd/xpbd.h"
#include "model/transformer.h"

/* WEFT_METHOD_EXTERNAL: the host writes x_next (weft_garment_constrain); nothing to build. */
static weft_result external_create(weft_garment *g)
{
    (void)g;
    return WEFT_OK;
}

static void external_destroy(weft_garment *g) { (void)g; }

static weft_result external_step(weft_garment *g)
{
    (void)g;
    return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                      "weft_garment_step: an external garment is stepped by weft_garment_constrain with the "
                      "host solver's positions");
}

static const weft_method_ops external_ops = {
    .name = "external",
    .supports_pins = false,
    .create = external_create,
    .destroy = external_destroy,
    .reset = NULL,
    .step = external_step,
};

/* One entry per weft_method; a method's folder defines its ops table. */
const weft_method_ops *weft__method_ops(weft_method method)
{
    switch (method) {
    case WEFT_METHOD_XPBD:
        return &weft__xpbd_ops;
    case WEFT_METHOD_XPBD_FAST:
        return &weft__xpbd_fast_ops;
    case WEFT_METHOD_LBS:
        return &weft__lbs_ops;
    case WEFT_METHOD_MODEL:
        return &weft__method_model;
    case WEFT_METHOD_EXTERNAL:
        return &external_ops;
    default:
        return NULL;
    }
}

#include "garment/garment.h"
#include "xpbd/xpbd.h"
#include "model/transformer.h"

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
    default:
        return NULL;
    }
}

#include "garment/garment.h"

/* One entry per weft_method; a method's folder defines its ops table. */
const weft_method_ops *weft__method_ops(weft_method method)
{
    switch (method) {
    case WEFT_METHOD_MODEL:
    case WEFT_METHOD_XPBD:
    case WEFT_METHOD_LBS:
    default:
        return NULL;
    }
}

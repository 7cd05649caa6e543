/* Temporary bootstrap: replaced by the real CPU detection and kernels (runtime/cpu, runtime/kernels). DELETE when those land. */
#include "core/core.h"
#include "cpu/cpu.h"
const char *weft_cpu_features_string(void){return "";}
weft_isa weft_cpu_best_isa(void){return WEFT_ISA_SCALAR;}
weft_result weft_cpu_resolve_isa(weft_isa r, weft_isa *o){*o=r==WEFT_ISA_AUTO?WEFT_ISA_SCALAR:r;return WEFT_OK;}
static const weft_kernels k={.isa=WEFT_ISA_SCALAR};
const weft_kernels *weft_kernels_for_isa(weft_isa i){return &k;}

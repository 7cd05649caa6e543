/* A host program built against an installed weft: creates a context and reports the build. */
#include <weft.h>

#include <stdio.h>

int main(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_result r = weft_context_create(&def, &ctx);
    if (r != WEFT_OK) {
        fprintf(stderr, "consumer: %s: %s\n", weft_result_string(r), weft_last_error());
        return 1;
    }
    printf("consumer: %s\n", weft_config_string());
    weft_context_destroy(ctx);
    return 0;
}

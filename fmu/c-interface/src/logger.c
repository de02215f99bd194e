/* The fmi2CallbackLogger an importer hands to every FMI 2.0 FMU.
 *
 * FMI 2.0 declares the logger as a variadic C function: its message is a printf format and the
 * FMU passes the arguments after it. Stable Rust can call variadic C functions but cannot
 * define one, so this shim does the one thing that needs C -- formatting with vsnprintf -- and
 * passes the finished text to a plain (non-variadic) callback. The componentEnvironment the
 * importer gave the FMU points at a struct whose first member is that callback and whose second
 * is the importer's own context (fmi_c::fmi2::LogForwarder). */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef void (*fmi_c_forward_fn)(void *context, const char *instance_name, int status,
                                 const char *category, const char *text);

struct fmi_c_log_forwarder {
    fmi_c_forward_fn forward;
    void *context;
};

static void deliver(void *environment, const char *instance_name, int status,
                    const char *category, const char *text) {
    const struct fmi_c_log_forwarder *f = environment;
    if (f != NULL && f->forward != NULL) {
        f->forward(f->context, instance_name, status, category, text);
    }
}

void fmi_c_fmi2_logger(void *environment, const char *instance_name, int status,
                       const char *category, const char *message, ...) {
    char small[1024];
    va_list args;

    if (message == NULL) {
        deliver(environment, instance_name, status, category, "(NULL message)");
        return;
    }
    va_start(args, message);
    int needed = vsnprintf(small, sizeof small, message, args);
    va_end(args);
    if (needed < 0) {
        /* A format the C library rejects: pass the raw format rather than lose the message. */
        deliver(environment, instance_name, status, category, message);
        return;
    }
    if ((size_t)needed < sizeof small) {
        deliver(environment, instance_name, status, category, small);
        return;
    }
    /* Long message: format again into a buffer of the exact size. */
    char *large = malloc((size_t)needed + 1);
    if (large == NULL) {
        deliver(environment, instance_name, status, category, small);
        return;
    }
    va_start(args, message);
    vsnprintf(large, (size_t)needed + 1, message, args);
    va_end(args);
    deliver(environment, instance_name, status, category, large);
    free(large);
}

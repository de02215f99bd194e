/* The fmi2CallbackLogger an importer hands to every FMI 2.0 FMU (and fmi_c_fmi1_logger, FMI 1.0's).
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

/* Formats `message` with `args` and hands the text to deliver(target, ...): the one body of
 * both versions' loggers. `again` is a copy of `args` for a second pass of a long message. */
static void format_and_deliver(void (*deliver_to)(void *, const char *, int, const char *, const char *),
                               void *target, const char *instance_name, int status, const char *category,
                               const char *message, va_list args, va_list again);

void fmi_c_fmi2_logger(void *environment, const char *instance_name, int status,
                       const char *category, const char *message, ...) {
    va_list args, again;
    if (message == NULL) {
        deliver(environment, instance_name, status, category, "(NULL message)");
        return;
    }
    va_start(args, message);
    va_start(again, message);
    format_and_deliver(deliver, environment, instance_name, status, category, message, args, again);
    va_end(again);
    va_end(args);
}

/* FMI 1.0: the logger gets the FMU's component, not a pointer of the importer's, so every
 * message goes to one sink for the process, which finds the instance by component or name. */
typedef void (*fmi_c_fmi1_sink_fn)(void *component, const char *instance_name, int status,
                                   const char *category, const char *text);
static fmi_c_fmi1_sink_fn fmi1_sink = NULL;

void fmi_c_fmi1_set_sink(fmi_c_fmi1_sink_fn sink) { fmi1_sink = sink; }

static void deliver_fmi1(void *component, const char *instance_name, int status,
                         const char *category, const char *text) {
    if (fmi1_sink != NULL) {
        fmi1_sink(component, instance_name, status, category, text);
    }
}

void fmi_c_fmi1_logger(void *component, const char *instance_name, int status,
                       const char *category, const char *message, ...) {
    va_list args, again;
    if (message == NULL) {
        deliver_fmi1(component, instance_name, status, category, "(NULL message)");
        return;
    }
    va_start(args, message);
    va_start(again, message);
    format_and_deliver(deliver_fmi1, component, instance_name, status, category, message, args, again);
    va_end(again);
    va_end(args);
}

static void format_and_deliver(void (*deliver_to)(void *, const char *, int, const char *, const char *),
                               void *target, const char *instance_name, int status, const char *category,
                               const char *message, va_list args, va_list again) {
    char small[1024];
    int needed = vsnprintf(small, sizeof small, message, args);
    if (needed < 0) {
        /* A format the C library rejects: pass the raw format rather than lose the message. */
        deliver_to(target, instance_name, status, category, message);
        return;
    }
    if ((size_t)needed < sizeof small) {
        deliver_to(target, instance_name, status, category, small);
        return;
    }
    /* Long message: format again into a buffer of the exact size. */
    char *large = malloc((size_t)needed + 1);
    if (large == NULL) {
        deliver_to(target, instance_name, status, category, small);
        return;
    }
    vsnprintf(large, (size_t)needed + 1, message, again);
    deliver_to(target, instance_name, status, category, large);
    free(large);
}

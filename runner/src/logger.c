/* The fmi2CallbackLogger the runner hands to every FMU.
 *
 * FMI 2.0 declares the logger as a variadic C function: its message is a printf format and the
 * FMU passes the arguments after it. Stable Rust can call variadic C functions but cannot
 * define one, so this shim does the one thing that needs C -- formatting with vsnprintf -- and
 * passes the finished text to a plain (non-variadic) Rust callback, runner_log_message. */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

/* Implemented in Rust (runner/src/fmi.rs). */
extern void runner_log_message(void *environment, const char *instance_name, int status,
                               const char *category, const char *text);

void runner_fmi_logger(void *environment, const char *instance_name, int status,
                       const char *category, const char *message, ...) {
    char small[1024];
    va_list args;

    if (message == NULL) {
        runner_log_message(environment, instance_name, status, category, "(NULL message)");
        return;
    }
    va_start(args, message);
    int needed = vsnprintf(small, sizeof small, message, args);
    va_end(args);
    if (needed < 0) {
        /* A format the C library rejects: pass the raw format rather than lose the message. */
        runner_log_message(environment, instance_name, status, category, message);
        return;
    }
    if ((size_t)needed < sizeof small) {
        runner_log_message(environment, instance_name, status, category, small);
        return;
    }
    /* Long message: format again into a buffer of the exact size. */
    char *large = malloc((size_t)needed + 1);
    if (large == NULL) {
        runner_log_message(environment, instance_name, status, category, small);
        return;
    }
    va_start(args, message);
    vsnprintf(large, (size_t)needed + 1, message, args);
    va_end(args);
    runner_log_message(environment, instance_name, status, category, large);
    free(large);
}

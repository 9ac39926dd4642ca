/* The FMI 2 logger an FMU is given: it formats the message as printf would with the arguments that
 * follow it (the logger's contract: `message` is a format, its varargs after it), which a Python
 * callback cannot read, and hands the text to the one sink the master registered, with the FMU's
 * componentEnvironment so the sink knows whose message it is. Used by wavecosim/fmi/fmu.py. */
#include <stdarg.h>
#include <stdio.h>

#include "fmilog.h"

#define MESSAGE_BYTES 4096             /* a longer message is cut here (the master keeps 2000 characters) */

static LogSink sink = NULL;

void fmilog_set_sink(LogSink to) {
    sink = to;
}

void fmilog_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    char text[MESSAGE_BYTES];
    va_list args;
    if (!sink) return;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    sink(env, instance, status, category, text);
}

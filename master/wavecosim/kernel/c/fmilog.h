/* The FMI 2 logger that formats an FMU's message with its printf arguments (fmilog.c, libfmilog.so;
 * wavecosim/fmi/fmu.py registers its sink and hands fmilog_logger to the FMUs). */
#ifndef WAVECOSIM_FMILOG_H
#define WAVECOSIM_FMILOG_H

#include "fmi2Functions.h"

/* Where a formatted message goes: (componentEnvironment, instance, status, category, text). */
typedef void (*LogSink)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String);

/* The one sink every message is handed to (NULL: messages are dropped). */
void fmilog_set_sink(LogSink to);

/* The logger an FMU is given: `message` formatted with the arguments after it, then handed to the sink. */
void fmilog_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...);

#endif

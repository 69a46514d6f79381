// report.h - the firmware's self-description: HELLO and STATUS responses.
#ifndef RBX1_REPORT_H
#define RBX1_REPORT_H

#include <stdint.h>

#include "rbx1_proto.h"

void report_hello(rbx1_hello_resp *r, uint8_t host_version, uint8_t last_seq);
void report_status(rbx1_status_resp *r);

#endif

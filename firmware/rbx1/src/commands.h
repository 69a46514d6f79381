// commands.h - one handler per request type: unpack into the named struct, check the state, act, pack the
// response. protocol.cpp has already checked the type and the payload length.
#ifndef RBX1_COMMANDS_H
#define RBX1_COMMANDS_H

#include <stdint.h>

#include "rbx1_proto.h"

// Executes frame; writes the response payload to out (RBX1_MAX_PAYLOAD bytes) and returns its length.
uint8_t cmd_execute(const rbx1_frame *frame, uint8_t *out);

#endif

// safety.h - e-stop (message), controlled stop, fault clearing and the host heartbeat watchdog.
// The e-stop input itself is watched by the stepper's interrupts; this module handles the requests.
#ifndef RBX1_SAFETY_H
#define RBX1_SAFETY_H

#include <stdint.h>

void safety_init(void);
// Any valid request restarts the heartbeat timer.
void safety_request_seen(void);
// ESTOP: all pulses stop at once, ESTOP_COMMAND latches.
void safety_estop(void);
// STOP (fault_at_rest = 0) or heartbeat loss: decelerate, flush; latch fault_at_rest once at rest.
void safety_stop(uint16_t fault_at_rest);
// CLEAR_FAULT: RBX1_OK, or RBX1_ESTOP_ACTIVE while the e-stop input is held.
uint8_t safety_clear_fault(void);
// Main loop: heartbeat expiry and the end of a controlled stop.
void safety_poll(void);

#endif

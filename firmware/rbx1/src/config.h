// config.h - compile-time options of the RBX1 firmware (sizes, rates, version); runtime settings live in settings.h.
#ifndef RBX1_FW_CONFIG_H
#define RBX1_FW_CONFIG_H

// Firmware version reported by HELLO.
#define FW_VERSION_MAJOR 1
#define FW_VERSION_MINOR 0
#define FW_VERSION_PATCH 0

// Motion queue entries (MOVE and GRIPPER). Each entry costs about 70 bytes of RAM on the AVR.
#define QUEUE_SIZE 16

// Serial baud rate at power-up (PROTOCOL.md: 115200 default).
#define SERIAL_BAUD 115200UL

// Step timer: Timer1 at F_CPU/8 = 2 MHz, so one tick is 0.5 us. Intervals longer than 16 bits are split in
// the ISR (see stepper.cpp), so any speed down to 1 step/s works.
#define STEP_TIMER_HZ 2000000UL

// The profile tick: a 1 kHz interrupt below the step interrupt that updates the dominant joint's velocity
// (trapezoid), polls the limit inputs, runs dwells and starts the next queue entry.
#define PROFILE_TICK_HZ 1000UL

// A partial frame older than this is dropped (PROTOCOL.md: inter-byte timeout).
#define FRAME_TIMEOUT_MS 50

// Look-ahead junctions (firmware/README.md, Look-ahead): the velocity jump a joint may make where two moves meet,
// as the lag (steps) a motor accelerating at its ACCEL builds while it follows the jump: dv <= sqrt(2 ACCEL lag).
// 4 steps is a quarter of a full step at the RAMPS' 16 microsteps (253 steps/s at the default ACCEL 8000); a start
// from rest at the stop rate sqrt(ACCEL / 2) lags a quarter of a microstep.
#define JUNCTION_LAG_STEPS 4

// Homing: at most this many steps are spent backing off a switch before homing fails.
#define HOMING_BACKOFF_MAX_STEPS 4000L
// Back-off speed is HOME_SPEED divided by this (slower release gives a repeatable switch point).
#define HOMING_BACKOFF_DIVISOR 4

#if QUEUE_SIZE < 2 || QUEUE_SIZE > 64
#error "QUEUE_SIZE must be 2..64 (queue_free is reported in a byte and the AVR has 8 KiB of RAM)"
#endif
#if STEP_TIMER_HZ != 2000000UL
#error "stepper.cpp's velocity-to-interval constant assumes a 2 MHz step timer"
#endif

#endif

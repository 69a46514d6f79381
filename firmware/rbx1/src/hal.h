// hal.h - the hardware seam: timers, pins, UART, EEPROM and watchdog, implemented by hal_avr.cpp on the board
// and by firmware/sim/hal_sim.cpp on the host. The core never touches a register.
#ifndef RBX1_HAL_H
#define RBX1_HAL_H

#include <stdint.h>

#include "rbx1_messages.h"

// Brings the board up: outputs in their safe state (drivers disabled, no step pulse, no servo pulse), inputs
// with pull-ups, serial at SERIAL_BAUD, the 1 kHz profile tick running, the step timer stopped, watchdog on.
void hal_init(void);
// Milliseconds since power-up (wraps).
uint32_t hal_millis(void);

// Next received byte, or -1 when none is waiting. Never blocks.
int16_t hal_serial_read(void);
// Queues bytes for sending (may wait for room in the transmit buffer; interrupts keep running).
void hal_serial_write(const uint8_t *data, uint8_t n);

// Step timer (2 MHz ticks): start fires st_step_isr() after `ticks`; period (called inside st_step_isr) sets the
// time to the next call; stop cancels it. ticks is 2..65535.
void hal_step_timer_start(uint16_t ticks);

// Outputs. Masks have one bit per joint (bit 0 = J1).
void hal_drivers_enable(uint8_t on);      // all EN pins
void hal_servo_write(uint16_t pulse_us);  // 0 = no pulses (servo limp)

#ifdef __AVR__
#include "hal_avr.h"  // the step-path functions below as inline code, for a short ISR
#else
void hal_step_timer_period(uint16_t ticks);
void hal_step_timer_stop(void);
void hal_step_high(uint8_t mask);        // raise STEP of the joints in mask
void hal_step_low(void);                 // lower every STEP
void hal_dir_write(uint8_t positive_mask);  // DIR per joint: 1 = positive (pins.h RBX1_DIR_POSITIVE_LEVEL)
// Inputs, already converted to "1 = triggered/asserted".
uint8_t hal_limit_inputs(void);  // bit per joint
uint8_t hal_estop_input(void);
#endif

// EEPROM (4 KiB on the ATmega2560). write only writes when the byte differs (saves wear and time).
uint8_t hal_eeprom_read(uint16_t addr);
void hal_eeprom_write(uint16_t addr, uint8_t value);

// Watchdog: kick from the main loop; reset_by_watchdog tells whether the last reset was the watchdog's.
void hal_watchdog_kick(void);
uint8_t hal_reset_by_watchdog(void);

// Interrupt masking around data shared with the ISRs (also a compiler barrier).
typedef uint8_t hal_irq_state;
hal_irq_state hal_irq_save(void);
void hal_irq_restore(hal_irq_state s);

// Called (from the profile tick) when a queue entry completes; the simulator writes its move log from it.
// kind: 0 = move, 1 = gripper. start/end: positions when the entry began and ended.
void hal_entry_done(uint8_t kind, uint16_t n, const int32_t target[RBX1_JOINTS], const int32_t start[RBX1_JOINTS],
                    const int32_t end[RBX1_JOINTS], uint16_t duration_ms, uint16_t pulse_us);

// Firmware capabilities the board adds to HELLO (RBX1_CAP_SIMULATED on the host).
uint16_t hal_capabilities(void);

#endif

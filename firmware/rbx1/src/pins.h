/* pins.h - the single RAMPS 1.4-style pin map of the RBX1 controller (Arduino Mega 2560): AVR port letter and bit
 * per signal. Plain #defines so that host C/C++ (rbx1-avrsim) reads the same map as the firmware. */
#ifndef RBX1_PINS_H
#define RBX1_PINS_H

/* Electrical conventions (also read by simulators):
 * - STEP: a pulse is a high level of at least 2 us; the step counts on the rising edge.
 * - DIR: high = positive step direction (before the per-joint INVERT_DIR setting, which flips the pin level).
 * - EN: active low (A4988/DRV8825 ENABLE input): low = driver on. Drivers are off (high) at power-up.
 * - LIMIT and ESTOP inputs use the internal pull-ups and are wired normally-closed to GND, so a pressed switch
 *   or a broken wire reads HIGH = triggered/asserted (fail-safe, as Marlin's default for RAMPS endstops). */
#define RBX1_STEP_ACTIVE_LEVEL 1
#define RBX1_DIR_POSITIVE_LEVEL 1
#define RBX1_EN_ACTIVE_LEVEL 0
#define RBX1_LIMIT_TRIGGERED_LEVEL 1
#define RBX1_ESTOP_ASSERTED_LEVEL 1

/* Joint 1: RAMPS X driver, X_MIN endstop. */
#define RBX1_J1_STEP_PORT 'F' /* D54 (A0) */
#define RBX1_J1_STEP_BIT 0
#define RBX1_J1_DIR_PORT 'F' /* D55 (A1) */
#define RBX1_J1_DIR_BIT 1
#define RBX1_J1_EN_PORT 'D' /* D38 */
#define RBX1_J1_EN_BIT 7
#define RBX1_J1_LIMIT_PORT 'E' /* D3, X_MIN */
#define RBX1_J1_LIMIT_BIT 5

/* Joint 2: RAMPS Y driver, Y_MIN endstop. */
#define RBX1_J2_STEP_PORT 'F' /* D60 (A6) */
#define RBX1_J2_STEP_BIT 6
#define RBX1_J2_DIR_PORT 'F' /* D61 (A7) */
#define RBX1_J2_DIR_BIT 7
#define RBX1_J2_EN_PORT 'F' /* D56 (A2) */
#define RBX1_J2_EN_BIT 2
#define RBX1_J2_LIMIT_PORT 'J' /* D14, Y_MIN */
#define RBX1_J2_LIMIT_BIT 1

/* Joint 3: RAMPS Z driver, Z_MIN endstop. */
#define RBX1_J3_STEP_PORT 'L' /* D46 */
#define RBX1_J3_STEP_BIT 3
#define RBX1_J3_DIR_PORT 'L' /* D48 */
#define RBX1_J3_DIR_BIT 1
#define RBX1_J3_EN_PORT 'K' /* D62 (A8) */
#define RBX1_J3_EN_BIT 0
#define RBX1_J3_LIMIT_PORT 'D' /* D18, Z_MIN */
#define RBX1_J3_LIMIT_BIT 3

/* Joint 4: RAMPS E0 driver, X_MAX endstop. */
#define RBX1_J4_STEP_PORT 'A' /* D26 */
#define RBX1_J4_STEP_BIT 4
#define RBX1_J4_DIR_PORT 'A' /* D28 */
#define RBX1_J4_DIR_BIT 6
#define RBX1_J4_EN_PORT 'A' /* D24 */
#define RBX1_J4_EN_BIT 2
#define RBX1_J4_LIMIT_PORT 'E' /* D2, X_MAX */
#define RBX1_J4_LIMIT_BIT 4

/* Joint 5: RAMPS E1 driver, Y_MAX endstop. */
#define RBX1_J5_STEP_PORT 'C' /* D36 */
#define RBX1_J5_STEP_BIT 1
#define RBX1_J5_DIR_PORT 'C' /* D34 */
#define RBX1_J5_DIR_BIT 3
#define RBX1_J5_EN_PORT 'C' /* D30 */
#define RBX1_J5_EN_BIT 7
#define RBX1_J5_LIMIT_PORT 'J' /* D15, Y_MAX */
#define RBX1_J5_LIMIT_BIT 0

/* Joint 6: a sixth driver on the AUX-4 header (external driver board), Z_MAX endstop. */
#define RBX1_J6_STEP_PORT 'L' /* D44 */
#define RBX1_J6_STEP_BIT 5
#define RBX1_J6_DIR_PORT 'L' /* D42 */
#define RBX1_J6_DIR_BIT 7
#define RBX1_J6_EN_PORT 'G' /* D40 */
#define RBX1_J6_EN_BIT 1
#define RBX1_J6_LIMIT_PORT 'D' /* D19, Z_MAX */
#define RBX1_J6_LIMIT_BIT 2

/* E-stop input: AUX-4 header. */
#define RBX1_ESTOP_PORT 'G' /* D41 */
#define RBX1_ESTOP_BIT 0

/* Gripper servo: RAMPS SERVO2 header pin, driven by Timer4's hardware PWM (OC4A, 50 Hz). */
#define RBX1_SERVO_PORT 'H' /* D6, OC4A */
#define RBX1_SERVO_BIT 3

#endif

// settings.h - runtime configuration (PROTOCOL.md keys): ranges from the protocol's key table, kept in EEPROM
// with a layout version and a CRC; blank or corrupt EEPROM gives the defaults.
#ifndef RBX1_SETTINGS_H
#define RBX1_SETTINGS_H

#include <stdint.h>

#include "rbx1_messages.h"

#define SETTINGS_JOINT_KEYS 8   // RBX1_KEY_SOFT_MIN (1) .. RBX1_KEY_INVERT_DIR (8)
#define SETTINGS_GLOBAL_KEYS 3  // RBX1_KEY_HEARTBEAT_MS (16) .. RBX1_KEY_GRIPPER_MAX_US (18)
#define SETTINGS_GLOBAL_FIRST 16
#define SETTINGS_VERSION 1      // bump when the layout changes: old EEPROM contents then read as corrupt
#define SETTINGS_EEPROM_ADDR 0

struct settings_t {
  int32_t joint[RBX1_JOINTS][SETTINGS_JOINT_KEYS];  // indexed [joint][key - 1]
  int32_t global[SETTINGS_GLOBAL_KEYS];   // indexed [key - 16]
};
extern settings_t settings;

// Shorthands for the hot readers.
#define SETTING(j, key) (settings.joint[(j)][(key) - 1])
#define SETTING_GLOBAL(key) (settings.global[(key) - SETTINGS_GLOBAL_FIRST])

// Loads from EEPROM. Returns 1 when valid, 0 when blank/corrupt (defaults loaded, EEPROM left as it is).
uint8_t settings_load(void);
// Factory defaults into RAM (not saved).
void settings_defaults(void);
// Writes to EEPROM and reads back. Returns RBX1_OK or RBX1_EEPROM_ERROR.
uint8_t settings_save(void);
// Value of a key: RBX1_OK or RBX1_BAD_ARG (unknown key, wrong joint for its scope).
uint8_t settings_get(uint8_t joint, uint8_t key, int32_t *value);
// Validates (range, SOFT_MIN <= SOFT_MAX, GRIPPER_MIN_US <= GRIPPER_MAX_US), stores and saves.
// Returns RBX1_OK, RBX1_BAD_ARG or RBX1_EEPROM_ERROR.
uint8_t settings_set(uint8_t joint, uint8_t key, int32_t value);

#endif

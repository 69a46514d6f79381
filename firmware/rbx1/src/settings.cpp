// settings.cpp - runtime configuration: defaults and ranges from the protocol's key table, EEPROM persistence.
#include "settings.h"

#include <string.h>

#include "hal.h"
#include "rbx1_proto.h"

settings_t settings;

// EEPROM image: magic+version, the settings struct, CRC-16 over both (little-endian).
#define SETTINGS_MAGIC 0x5242u  // "RB"

void settings_defaults(void) {
  for (uint8_t k = 1; k <= SETTINGS_JOINT_KEYS; k++) {
    const rbx1_key_info *info = rbx1_key_lookup(k);
    int32_t v = info ? info->default_value : 0;
    for (uint8_t j = 0; j < RBX1_JOINTS; j++) settings.joint[j][k - 1] = v;
  }
  for (uint8_t k = 0; k < SETTINGS_GLOBAL_KEYS; k++) {
    const rbx1_key_info *info = rbx1_key_lookup((uint8_t)(SETTINGS_GLOBAL_FIRST + k));
    settings.global[k] = info ? info->default_value : 0;
  }
}

// CRC-16/CCITT-FALSE step (poly 0x1021, no table). The link's frames moved to CRC-32 (protocol version 4); the
// EEPROM image keeps this CRC so that boards keep their settings across the reflash.
static uint16_t crc16_update(uint16_t crc, uint8_t byte) {
  uint8_t x = (uint8_t)((crc >> 8) ^ byte);
  x ^= (uint8_t)(x >> 4);
  return (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
}

static uint16_t image_crc(const uint8_t *header, const settings_t *s) {
  uint16_t crc = 0xFFFFu;
  for (uint8_t i = 0; i < 4; i++) crc = crc16_update(crc, header[i]);
  const uint8_t *p = (const uint8_t *)s;
  for (uint16_t i = 0; i < sizeof(settings_t); i++) crc = crc16_update(crc, p[i]);
  return crc;
}

static void header_bytes(uint8_t *h) {
  h[0] = (uint8_t)(SETTINGS_MAGIC & 0xFF);
  h[1] = (uint8_t)(SETTINGS_MAGIC >> 8);
  h[2] = SETTINGS_VERSION;
  h[3] = (uint8_t)sizeof(settings_t);
}

uint8_t settings_load(void) {
  uint8_t h[4], want[4];
  header_bytes(want);
  uint16_t a = SETTINGS_EEPROM_ADDR;
  for (uint8_t i = 0; i < 4; i++) h[i] = hal_eeprom_read(a++);
  uint8_t *p = (uint8_t *)&settings;  // read in place: a bad image is replaced by the defaults below
  for (uint16_t i = 0; i < sizeof(settings_t); i++) p[i] = hal_eeprom_read(a++);
  uint16_t crc = (uint16_t)(hal_eeprom_read(a) | (hal_eeprom_read((uint16_t)(a + 1)) << 8));
  if (memcmp(h, want, 4) != 0 || crc != image_crc(h, &settings)) {
    settings_defaults();
    return 0;
  }
  return 1;
}

uint8_t settings_save(void) {
  uint8_t h[4];
  header_bytes(h);
  uint16_t crc = image_crc(h, &settings);
  uint16_t a = SETTINGS_EEPROM_ADDR;
  for (uint8_t i = 0; i < 4; i++) {
    hal_eeprom_write(a++, h[i]);
    hal_watchdog_kick();  // each changed byte takes 3.4 ms on the AVR
  }
  const uint8_t *p = (const uint8_t *)&settings;
  for (uint16_t i = 0; i < sizeof(settings_t); i++) {
    hal_eeprom_write(a++, p[i]);
    hal_watchdog_kick();
  }
  hal_eeprom_write(a, (uint8_t)(crc & 0xFF));
  hal_eeprom_write((uint16_t)(a + 1), (uint8_t)(crc >> 8));
  hal_watchdog_kick();
  // Read back: a worn or absent EEPROM is reported, not assumed.
  a = SETTINGS_EEPROM_ADDR + 4;
  for (uint16_t i = 0; i < sizeof(settings_t); i++)
    if (hal_eeprom_read(a++) != p[i]) return RBX1_EEPROM_ERROR;
  if (hal_eeprom_read(a) != (uint8_t)(crc & 0xFF) || hal_eeprom_read((uint16_t)(a + 1)) != (uint8_t)(crc >> 8))
    return RBX1_EEPROM_ERROR;
  return RBX1_OK;
}

// Where a key's value lives, or NULL for an unknown key / wrong joint.
static int32_t *slot(uint8_t joint, uint8_t key, const rbx1_key_info **info_out) {
  const rbx1_key_info *info = rbx1_key_lookup(key);
  if (!info) return 0;
  if (info->is_global) {
    if (joint != RBX1_GLOBAL_JOINT || key < SETTINGS_GLOBAL_FIRST ||
        key >= SETTINGS_GLOBAL_FIRST + SETTINGS_GLOBAL_KEYS)
      return 0;
    if (info_out) *info_out = info;
    return &settings.global[key - SETTINGS_GLOBAL_FIRST];
  }
  if (joint >= RBX1_JOINTS || key < 1 || key > SETTINGS_JOINT_KEYS) return 0;
  if (info_out) *info_out = info;
  return &settings.joint[joint][key - 1];
}

uint8_t settings_get(uint8_t joint, uint8_t key, int32_t *value) {
  int32_t *s = slot(joint, key, 0);
  if (!s) return RBX1_BAD_ARG;
  *value = *s;
  return RBX1_OK;
}

uint8_t settings_set(uint8_t joint, uint8_t key, int32_t value) {
  const rbx1_key_info *info = 0;
  int32_t *s = slot(joint, key, &info);
  if (!s) return RBX1_BAD_ARG;
  int32_t lo = info->min, hi = info->max;  // copy: on AVR info points to a buffer reused by the next lookup
  if (value < lo || value > hi) return RBX1_BAD_ARG;
  // Cross-key rules: the pair must stay ordered.
  if (key == RBX1_KEY_SOFT_MIN && value > SETTING(joint, RBX1_KEY_SOFT_MAX)) return RBX1_BAD_ARG;
  if (key == RBX1_KEY_SOFT_MAX && value < SETTING(joint, RBX1_KEY_SOFT_MIN)) return RBX1_BAD_ARG;
  if (key == RBX1_KEY_GRIPPER_MIN_US && value > SETTING_GLOBAL(RBX1_KEY_GRIPPER_MAX_US)) return RBX1_BAD_ARG;
  if (key == RBX1_KEY_GRIPPER_MAX_US && value < SETTING_GLOBAL(RBX1_KEY_GRIPPER_MIN_US)) return RBX1_BAD_ARG;
  *s = value;
  return settings_save();
}

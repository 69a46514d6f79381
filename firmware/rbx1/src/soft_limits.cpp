// soft_limits.cpp - soft limit check of MOVE targets against the configured per-joint range.
#include "soft_limits.h"

#include "rbx1_proto.h"
#include "settings.h"

uint8_t soft_limits_check(const int32_t target[RBX1_JOINTS]) {
  for (uint8_t j = 0; j < RBX1_JOINTS; j++)
    if (target[j] < SETTING(j, RBX1_KEY_SOFT_MIN) || target[j] > SETTING(j, RBX1_KEY_SOFT_MAX))
      return RBX1_SOFT_LIMIT;
  return RBX1_OK;
}

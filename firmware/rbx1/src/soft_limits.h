// soft_limits.h - soft limits: a target outside any joint's SOFT_MIN..SOFT_MAX rejects the whole move.
// (Limit switches are watched by the stepper's profile tick: a new trigger while moving is LIMIT_HIT.)
#ifndef RBX1_SOFT_LIMITS_H
#define RBX1_SOFT_LIMITS_H

#include <stdint.h>

#include "rbx1_messages.h"

// RBX1_OK, or RBX1_SOFT_LIMIT if any joint's target is outside its soft limits.
uint8_t soft_limits_check(const int32_t target[RBX1_JOINTS]);

#endif

// commands.cpp - request handlers (PROTOCOL.md "Messages"); each states its wire format and valid states.
#include "commands.h"

#include "gripper.h"
#include "hal.h"
#include "homing.h"
#include "soft_limits.h"
#include "planner.h"
#include "protocol.h"
#include "queue.h"
#include "report.h"
#include "safety.h"
#include "settings.h"
#include "stepper.h"
#include "system.h"

// Motion requests (MOVE, GRIPPER) are valid in IDLE and MOVING.
static uint8_t motion_allowed(uint8_t need_enabled) {
  uint8_t state = sys_state();
  if (state == RBX1_STATE_FAULT) return RBX1_FAULT_ACTIVE;
  if (state != RBX1_STATE_IDLE && state != RBX1_STATE_MOVING) return RBX1_BUSY;
  if (need_enabled && !sys.enabled) return RBX1_DISABLED;
  if (!sys_all_homed()) return RBX1_NOT_HOMED;
  return RBX1_OK;
}

// Requests valid only at rest (IDLE, or FAULT when fault_ok).
static uint8_t rest_allowed(uint8_t fault_ok) {
  uint8_t state = sys_state();
  if (state == RBX1_STATE_IDLE) return RBX1_OK;
  if (state == RBX1_STATE_FAULT) return fault_ok ? RBX1_OK : RBX1_FAULT_ACTIVE;
  return RBX1_BUSY;
}

// HELLO proto_version u8 -> proto_version, fw_major/minor/patch, joints, queue_size, capabilities u16, last_seq,
// window. Any state; protocol.cpp has already started a new session (the window) for it.
static uint8_t cmd_hello(const rbx1_frame *f, uint8_t *out) {
  rbx1_hello_req req;
  rbx1_hello_resp r;
  rbx1_hello_req_unpack(&req, f->payload, f->len);
  report_hello(&r, req.proto_version, protocol_last_seq());
  return rbx1_hello_resp_pack(&r, out);
}

// STATUS — -> state, faults u16, homed, inputs, enabled, queue_free, moves_done u16, gripper_us u16, position i32[6].
static uint8_t cmd_status(uint8_t *out) {
  rbx1_status_resp r;
  report_status(&r);
  return rbx1_status_resp_pack(&r, out);
}

// MOVE target i32[6], duration_ms u16 -> queue_free. IDLE, MOVING; enabled, homed, inside soft limits.
static uint8_t cmd_move(const rbx1_frame *f, uint8_t *out) {
  rbx1_move_req req;
  rbx1_move_resp r;
  rbx1_move_req_unpack(&req, f->payload, f->len);
  r.status = motion_allowed(1);
  if (r.status == RBX1_OK) r.status = soft_limits_check(req.target);
  if (r.status == RBX1_OK) {
    plan_block *b = queue_reserve();
    if (!b) {
      r.status = RBX1_QUEUE_FULL;
    } else {
      int32_t start[RBX1_JOINTS], pos[RBX1_JOINTS];
      st_position(pos);
      queue_plan_start(start, pos);
      r.status = plan_move(b, start, req.target, req.duration_ms, queue_last());
      if (r.status == RBX1_OK && !queue_commit()) r.status = RBX1_FAULT_ACTIVE;  // flushed meanwhile
      if (r.status == RBX1_OK) planner_mark_stale();  // recalculated after the answer is out
    }
  }
  r.queue_free = queue_free();
  return rbx1_move_resp_pack(&r, out);
}

// GRIPPER pulse_us u16, dwell_ms u16 -> queue_free. IDLE, MOVING; homed; pulse inside GRIPPER_MIN/MAX_US.
static uint8_t cmd_gripper(const rbx1_frame *f, uint8_t *out) {
  rbx1_gripper_req req;
  rbx1_gripper_resp r;
  rbx1_gripper_req_unpack(&req, f->payload, f->len);
  r.status = motion_allowed(0);  // the servo does not need the stepper drivers
  if (r.status == RBX1_OK) r.status = gripper_check(req.pulse_us);
  if (r.status == RBX1_OK) {
    plan_block *b = queue_reserve();
    if (!b) {
      r.status = RBX1_QUEUE_FULL;
    } else {
      plan_gripper(b, req.pulse_us, req.dwell_ms);
      if (!queue_commit()) r.status = RBX1_FAULT_ACTIVE;
    }
  }
  r.queue_free = queue_free();
  return rbx1_gripper_resp_pack(&r, out);
}

// HOME joint_mask u8 (0 = all) -> —. IDLE; drivers enabled.
static uint8_t cmd_home(const rbx1_frame *f, uint8_t *out) {
  rbx1_home_req req;
  rbx1_home_resp r;
  rbx1_home_req_unpack(&req, f->payload, f->len);
  r.status = rest_allowed(0);
  if (r.status == RBX1_OK && (req.joint_mask & (uint8_t)~RBX1_ALL_JOINTS_MASK)) r.status = RBX1_BAD_ARG;
  if (r.status == RBX1_OK && !sys.enabled) r.status = RBX1_DISABLED;
  if (r.status == RBX1_OK) homing_start(req.joint_mask ? req.joint_mask : RBX1_ALL_JOINTS_MASK);
  return rbx1_home_resp_pack(&r, out);
}

// STOP — -> —. Any state: controlled stop, queue flushed.
static uint8_t cmd_stop(uint8_t *out) {
  rbx1_stop_resp r;
  safety_stop(0);
  r.status = RBX1_OK;
  return rbx1_stop_resp_pack(&r, out);
}

// ESTOP — -> —. Any state, outside the window (never deduplicated): pulses stop at once, ESTOP_COMMAND latches.
static uint8_t cmd_estop(uint8_t *out) {
  rbx1_estop_resp r;
  safety_estop();
  r.status = RBX1_OK;
  return rbx1_estop_resp_pack(&r, out);
}

// CLEAR_FAULT — -> —. Any state; ESTOP_ACTIVE while the e-stop input is held.
static uint8_t cmd_clear_fault(uint8_t *out) {
  rbx1_clear_fault_resp r;
  r.status = safety_clear_fault();
  return rbx1_clear_fault_resp_pack(&r, out);
}

// ENABLE enable u8 (0/1) -> —. IDLE, FAULT.
static uint8_t cmd_enable(const rbx1_frame *f, uint8_t *out) {
  rbx1_enable_req req;
  rbx1_enable_resp r;
  rbx1_enable_req_unpack(&req, f->payload, f->len);
  r.status = rest_allowed(1);
  if (r.status == RBX1_OK && req.enable > 1) r.status = RBX1_BAD_ARG;
  if (r.status == RBX1_OK) {
    sys.enabled = req.enable;
    hal_drivers_enable(req.enable);
  }
  return rbx1_enable_resp_pack(&r, out);
}

// SET_POSITION position i32[6] -> —. IDLE, inside the soft limits: declares the positions, marks every joint homed.
static uint8_t cmd_set_position(const rbx1_frame *f, uint8_t *out) {
  rbx1_set_position_req req;
  rbx1_set_position_resp r;
  rbx1_set_position_req_unpack(&req, f->payload, f->len);
  r.status = rest_allowed(0);
  if (r.status == RBX1_OK) r.status = soft_limits_check(req.position);
  if (r.status == RBX1_OK) {
    st_set_position(req.position);
    sys.homed = RBX1_ALL_JOINTS_MASK;
  }
  return rbx1_set_position_resp_pack(&r, out);
}

// CONFIG_GET joint u8, key u8 -> value i32. Any state.
static uint8_t cmd_config_get(const rbx1_frame *f, uint8_t *out) {
  rbx1_config_get_req req;
  rbx1_config_get_resp r;
  rbx1_config_get_req_unpack(&req, f->payload, f->len);
  r.value = 0;
  r.status = settings_get(req.joint, req.key, &r.value);
  return rbx1_config_get_resp_pack(&r, out);
}

// CONFIG_SET joint u8, key u8, value i32 -> —. IDLE, FAULT: validated, then saved to EEPROM.
static uint8_t cmd_config_set(const rbx1_frame *f, uint8_t *out) {
  rbx1_config_set_req req;
  rbx1_config_set_resp r;
  rbx1_config_set_req_unpack(&req, f->payload, f->len);
  r.status = rest_allowed(1);
  if (r.status == RBX1_OK) r.status = settings_set(req.joint, req.key, req.value);
  return rbx1_config_set_resp_pack(&r, out);
}

// CONFIG_RESET — -> —. IDLE, FAULT: factory defaults, saved.
static uint8_t cmd_config_reset(uint8_t *out) {
  rbx1_config_reset_resp r;
  r.status = rest_allowed(1);
  if (r.status == RBX1_OK) {
    settings_defaults();
    r.status = settings_save();
  }
  return rbx1_config_reset_resp_pack(&r, out);
}

uint8_t cmd_execute(const rbx1_frame *f, uint8_t *out) {
  switch (f->type) {
    case RBX1_MSG_HELLO: return cmd_hello(f, out);
    case RBX1_MSG_STATUS: return cmd_status(out);
    case RBX1_MSG_MOVE: return cmd_move(f, out);
    case RBX1_MSG_GRIPPER: return cmd_gripper(f, out);
    case RBX1_MSG_HOME: return cmd_home(f, out);
    case RBX1_MSG_STOP: return cmd_stop(out);
    case RBX1_MSG_ESTOP: return cmd_estop(out);
    case RBX1_MSG_CLEAR_FAULT: return cmd_clear_fault(out);
    case RBX1_MSG_ENABLE: return cmd_enable(f, out);
    case RBX1_MSG_SET_POSITION: return cmd_set_position(f, out);
    case RBX1_MSG_CONFIG_GET: return cmd_config_get(f, out);
    case RBX1_MSG_CONFIG_SET: return cmd_config_set(f, out);
    case RBX1_MSG_CONFIG_RESET: return cmd_config_reset(out);
    default: {  // HEARTBEAT: its arrival (any valid request) restarts the heartbeat timer
      rbx1_heartbeat_resp r;
      r.status = RBX1_OK;
      return rbx1_heartbeat_resp_pack(&r, out);
    }
  }
}

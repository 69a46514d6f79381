// report.cpp - HELLO (versions, sizes, capabilities) and STATUS (state, faults, inputs, positions) contents.
#include "report.h"

#include "config.h"
#include "rbx1_window.h"
#include "hal.h"
#include "queue.h"
#include "stepper.h"
#include "system.h"

void report_hello(rbx1_hello_resp *r, uint8_t host_version, uint8_t last_seq) {
  r->status = host_version == RBX1_PROTO_VERSION ? RBX1_OK : RBX1_BAD_VERSION;
  r->proto_version = RBX1_PROTO_VERSION;
  r->fw_major = FW_VERSION_MAJOR;
  r->fw_minor = FW_VERSION_MINOR;
  r->fw_patch = FW_VERSION_PATCH;
  r->joints = RBX1_JOINTS;
  r->queue_size = QUEUE_SIZE;
  r->capabilities = (uint16_t)(RBX1_CAP_GRIPPER | RBX1_CAP_EEPROM_CONFIG | RBX1_CAP_ESTOP_INPUT |
                               RBX1_CAP_LIMIT_SWITCHES | hal_capabilities());
  r->last_seq = last_seq;
  r->window = RBX1_WINDOW;
}

void report_status(rbx1_status_resp *r) {
  r->status = RBX1_OK;
  r->state = sys_state();
  r->faults = sys_faults();
  r->homed = sys.homed;
  r->inputs = (uint8_t)(hal_limit_inputs() | (hal_estop_input() ? RBX1_INPUT_ESTOP : 0));
  r->enabled = sys.enabled;
  r->gripper_us = st_gripper_us();
  st_position(r->position);
  // The queue's counters in one snapshot: moves_accepted = moves_done + moves_flushed + queued entries.
  hal_irq_state s = hal_irq_save();
  r->queue_free = queue_free();
  r->moves_done = st_moves_done();
  r->moves_accepted = queue_accepted();
  r->moves_flushed = queue_flushed();
  hal_irq_restore(s);
}

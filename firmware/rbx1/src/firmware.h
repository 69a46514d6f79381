// firmware.h - the firmware's entry points: fw_setup() once at power-up (or reset), fw_loop() forever.
#ifndef RBX1_FIRMWARE_H
#define RBX1_FIRMWARE_H

void fw_setup(void);
void fw_loop(void);

#endif

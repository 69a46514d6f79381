// rbx1.ino - RBX1 arm firmware for the Arduino Mega 2560 (RAMPS 1.4-style pins): see ../README.md.
// Everything lives in src/; the protocol library is the Arduino library "rbx1proto" (protocol/ in this repo).
#include "src/firmware.h"

void setup() { fw_setup(); }

void loop() { fw_loop(); }

// protocol.h - the link: reads UART bytes into the frame decoder, NAKs rejected frames, keeps the window (SEQ order,
// at-most-once over the last RBX1_WINDOW requests), dispatches requests to commands.cpp and sends the responses.
#ifndef RBX1_PROTOCOL_H
#define RBX1_PROTOCOL_H

#include <stdint.h>

void protocol_init(void);
// Main loop: handles the bytes received so far (a bounded number per call).
void protocol_poll(void);
// HELLO's last_seq: the SEQ of the last request answered before the HELLO being handled, 0xFF when none.
uint8_t protocol_last_seq(void);

#endif

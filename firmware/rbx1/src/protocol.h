// protocol.h - the link: reads UART bytes into the frame decoder, NAKs rejected frames, suppresses duplicates,
// dispatches requests to commands.cpp and sends the responses.
#ifndef RBX1_PROTOCOL_H
#define RBX1_PROTOCOL_H

#include <stdint.h>

void protocol_init(void);
// Main loop: handles the bytes received so far (a bounded number per call).
void protocol_poll(void);

#endif

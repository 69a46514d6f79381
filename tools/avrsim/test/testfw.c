/* testfw.c - a tiny ATmega2560 program that exercises rbx1-avrsim without the real firmware: line commands on
 * UART0 (115200 8N1) pulse STEP pins from a TIMER1 ISR, read the limit/e-stop inputs, and use EEPROM/watchdog. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pins.h" /* firmware/rbx1/src/pins.h */

/* PINx, DDRx, PORTx are consecutive on the ATmega2560; map the pin map's port letters onto them. */
static volatile uint8_t *pin_reg(char port) {
  switch (port) {
    case 'A': return &PINA; case 'B': return &PINB; case 'C': return &PINC; case 'D': return &PIND;
    case 'E': return &PINE; case 'F': return &PINF; case 'G': return &PING; case 'H': return &PINH;
    case 'J': return &PINJ; case 'K': return &PINK; default: return &PINL;
  }
}
#define DDR_OF(p) (pin_reg(p) + 1)
#define PORT_OF(p) (pin_reg(p) + 2)

typedef struct { char step_port, dir_port, limit_port; uint8_t step_bit, dir_bit, limit_bit; } joint_pins;
static const joint_pins joints[6] = {
  {RBX1_J1_STEP_PORT, RBX1_J1_DIR_PORT, RBX1_J1_LIMIT_PORT, RBX1_J1_STEP_BIT, RBX1_J1_DIR_BIT, RBX1_J1_LIMIT_BIT},
  {RBX1_J2_STEP_PORT, RBX1_J2_DIR_PORT, RBX1_J2_LIMIT_PORT, RBX1_J2_STEP_BIT, RBX1_J2_DIR_BIT, RBX1_J2_LIMIT_BIT},
  {RBX1_J3_STEP_PORT, RBX1_J3_DIR_PORT, RBX1_J3_LIMIT_PORT, RBX1_J3_STEP_BIT, RBX1_J3_DIR_BIT, RBX1_J3_LIMIT_BIT},
  {RBX1_J4_STEP_PORT, RBX1_J4_DIR_PORT, RBX1_J4_LIMIT_PORT, RBX1_J4_STEP_BIT, RBX1_J4_DIR_BIT, RBX1_J4_LIMIT_BIT},
  {RBX1_J5_STEP_PORT, RBX1_J5_DIR_PORT, RBX1_J5_LIMIT_PORT, RBX1_J5_STEP_BIT, RBX1_J5_DIR_BIT, RBX1_J5_LIMIT_BIT},
  {RBX1_J6_STEP_PORT, RBX1_J6_DIR_PORT, RBX1_J6_LIMIT_PORT, RBX1_J6_STEP_BIT, RBX1_J6_DIR_BIT, RBX1_J6_LIMIT_BIT},
};

static volatile uint8_t step_mask;     /* joints pulsing */
static volatile uint16_t steps_left;   /* pulses still to send on each joint of step_mask */
static volatile uint8_t estop_lag;     /* pulses still sent after the e-stop input is seen (latency test) */
static uint8_t estop_lag_set;
static char line[40];
static uint8_t line_len;
static volatile char rx_buf[64];
static volatile uint8_t rx_head, rx_tail;

static volatile uint8_t int0_calls, int7_calls;
ISR(INT0_vect) { int0_calls++; }
ISR(INT7_vect) { int7_calls++; }

/* Raises INT7 (low priority) and then INT0 (high priority) while interrupts are off, so both are pending with the
 * lower-priority one older; both handlers must run once (simavr serves by priority without losing the other). */
static void priority_check(void) {
  DDRD |= _BV(PD0);
  DDRE |= _BV(PE7);
  PORTD &= (uint8_t)~_BV(PD0);
  PORTE &= (uint8_t)~_BV(PE7);
  EICRA |= _BV(ISC01) | _BV(ISC00);  /* rising edges */
  EICRB |= _BV(ISC71) | _BV(ISC70);
  EIFR = _BV(INTF0) | _BV(INTF7);
  EIMSK |= _BV(INT0) | _BV(INT7);
  cli();
  PORTE |= _BV(PE7);
  PORTD |= _BV(PD0);
  sei();
  __asm__ __volatile__("nop\n nop\n nop\n nop\n");
  PORTE &= (uint8_t)~_BV(PE7);
  PORTD &= (uint8_t)~_BV(PD0);
}

static uint8_t estop_raw(void) { return (*pin_reg(RBX1_ESTOP_PORT) >> RBX1_ESTOP_BIT) & 1; }

ISR(USART0_RX_vect) {
  uint8_t c = UDR0;
  uint8_t next = (uint8_t)((rx_head + 1) & 63);
  if (next != rx_tail) { rx_buf[rx_head] = (char)c; rx_head = next; }
}

/* One pulse per interrupt on every selected joint; the e-stop input (raw level 1 here) ends the run at once. */
ISR(TIMER1_COMPA_vect) {
  if (!steps_left) return;
  if (estop_raw()) {
    if (!estop_lag) { steps_left = 0; return; }
    estop_lag--;
  }
  for (uint8_t j = 0; j < 6; j++)
    if (step_mask & (1u << j)) *PORT_OF(joints[j].step_port) |= (uint8_t)(1u << joints[j].step_bit);
  __asm__ __volatile__("nop\n nop\n nop\n nop\n");
  for (uint8_t j = 0; j < 6; j++)
    if (step_mask & (1u << j)) *PORT_OF(joints[j].step_port) &= (uint8_t)~(1u << joints[j].step_bit);
  steps_left--;
}

static void put(char c) { while (!(UCSR0A & _BV(UDRE0))) {} UDR0 = (uint8_t)c; }
static void puts_uart(const char *s) { while (*s) put(*s++); }

static void reply_u(const char *tag, unsigned v) {
  char buf[24];
  snprintf(buf, sizeof buf, "%s %u\n", tag, v);
  puts_uart(buf);
}

static void command(char *s) {
  if (!strcmp(s, "ping")) { puts_uart("pong\n"); return; }
  if (!strncmp(s, "step ", 5)) {   /* step MASK COUNT DIRMASK */
    char *p = s + 5;
    uint8_t mask = (uint8_t)strtoul(p, &p, 0);
    uint16_t count = (uint16_t)strtoul(p, &p, 0);
    uint8_t dirs = (uint8_t)strtoul(p, &p, 0);
    for (uint8_t j = 0; j < 6; j++) {
      volatile uint8_t *port = PORT_OF(joints[j].dir_port);
      if (dirs & (1u << j)) *port |= (uint8_t)(1u << joints[j].dir_bit);
      else *port &= (uint8_t)~(1u << joints[j].dir_bit);
    }
    cli(); step_mask = mask; steps_left = count; estop_lag = estop_lag_set; sei();
    puts_uart("ok\n");
    return;
  }
  if (!strncmp(s, "lag ", 4)) { estop_lag_set = (uint8_t)atoi(s + 4); puts_uart("ok\n"); return; }
  if (!strcmp(s, "q")) { uint16_t left; cli(); left = steps_left; sei(); reply_u("left", left); return; }
  if (!strcmp(s, "in")) {
    unsigned v = 0;
    for (uint8_t j = 0; j < 6; j++) v |= (unsigned)((*pin_reg(joints[j].limit_port) >> joints[j].limit_bit) & 1) << j;
    v |= (unsigned)estop_raw() << 6;
    reply_u("in", v);
    return;
  }
  if (!strncmp(s, "ew ", 3)) { eeprom_update_byte((uint8_t *)0, (uint8_t)atoi(s + 3)); puts_uart("ok\n"); return; }
  if (!strcmp(s, "er")) { reply_u("ee", eeprom_read_byte((uint8_t *)0)); return; }
  if (!strcmp(s, "prio")) {
    priority_check();
    char buf[24];
    snprintf(buf, sizeof buf, "prio %u %u\n", int0_calls, int7_calls);
    puts_uart(buf);
    return;
  }
  if (!strcmp(s, "hang")) { wdt_enable(WDTO_15MS); for (;;) {} }
  puts_uart("err\n");
}

int main(void) {
  uint8_t mcusr = MCUSR;
  MCUSR = 0;
  wdt_disable();
  for (uint8_t j = 0; j < 6; j++) {
    *DDR_OF(joints[j].step_port) |= (uint8_t)(1u << joints[j].step_bit);
    *DDR_OF(joints[j].dir_port) |= (uint8_t)(1u << joints[j].dir_bit);
  }
  UBRR0 = 16;                 /* 115200 baud with U2X at 16 MHz, as Arduino does */
  UCSR0A = _BV(U2X0);
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
  TCCR1A = 0;
  TCCR1B = _BV(WGM12) | _BV(CS10);  /* CTC, no prescaler */
  OCR1A = 1599;                     /* 10 kHz step interrupt */
  TIMSK1 = _BV(OCIE1A);
  sei();
  reply_u("boot", (mcusr & _BV(WDRF)) ? 1u : 0u);
  for (;;) {
    if (rx_tail == rx_head) continue;
    char c = rx_buf[rx_tail];
    rx_tail = (uint8_t)((rx_tail + 1) & 63);
    if (c == '\n') { line[line_len] = 0; command(line); line_len = 0; }
    else if (line_len < sizeof line - 1) line[line_len++] = c;
  }
}

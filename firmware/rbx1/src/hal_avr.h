// hal_avr.h - inline AVR versions of the HAL's step-path functions (pins from pins.h), so the step ISR is short.
#ifndef RBX1_HAL_AVR_H
#define RBX1_HAL_AVR_H
#ifdef __AVR__

#include <avr/io.h>
#include <avr/interrupt.h>
#include "pins.h"

// Port registers from the port letters of pins.h; constant letters fold to one sbi/cbi or lds/sts.
#define HAL_PORT(c) (*((c) == 'A' ? &PORTA : (c) == 'B' ? &PORTB : (c) == 'C' ? &PORTC : (c) == 'D' ? &PORTD : \
  (c) == 'E' ? &PORTE : (c) == 'F' ? &PORTF : (c) == 'G' ? &PORTG : (c) == 'H' ? &PORTH : (c) == 'J' ? &PORTJ : \
  (c) == 'K' ? &PORTK : &PORTL))
#define HAL_DDR(c) (*((c) == 'A' ? &DDRA : (c) == 'B' ? &DDRB : (c) == 'C' ? &DDRC : (c) == 'D' ? &DDRD : \
  (c) == 'E' ? &DDRE : (c) == 'F' ? &DDRF : (c) == 'G' ? &DDRG : (c) == 'H' ? &DDRH : (c) == 'J' ? &DDRJ : \
  (c) == 'K' ? &DDRK : &DDRL))
#define HAL_PINR(c) (*((c) == 'A' ? &PINA : (c) == 'B' ? &PINB : (c) == 'C' ? &PINC : (c) == 'D' ? &PIND : \
  (c) == 'E' ? &PINE : (c) == 'F' ? &PINF : (c) == 'G' ? &PING : (c) == 'H' ? &PINH : (c) == 'J' ? &PINJ : \
  (c) == 'K' ? &PINK : &PINL))
#define HAL_SET(sig) (HAL_PORT(sig##_PORT) |= (uint8_t)(1u << sig##_BIT))
#define HAL_CLR(sig) (HAL_PORT(sig##_PORT) &= (uint8_t)~(1u << sig##_BIT))
#define HAL_READ(sig) ((HAL_PINR(sig##_PORT) >> sig##_BIT) & 1u)
#define HAL_WRITE(sig, v) do { if (v) HAL_SET(sig); else HAL_CLR(sig); } while (0)

// Inline and call-free, so the step ISR's prologue saves only the registers it uses.
#define HAL_INLINE static inline __attribute__((always_inline))

// Called from inside the step ISR only (interrupts off), so the 16-bit accesses need no guard. Timer1 runs in CTC
// mode: it counts from 0 after the compare match that raised this interrupt. A compare value written at or below
// the running count would miss its match on silicon (the counter runs on to 65535: a 32.8 ms stall), so the value
// is never written below TCNT1 + HAL_STEP_MARGIN ticks; the read and the write are a few cycles apart (under one
// tick), so a late write is impossible by construction. Such a clamped step comes late, never early.
#define HAL_STEP_MARGIN 4u
HAL_INLINE void hal_step_timer_period(uint16_t ticks) {
  uint16_t top = (uint16_t)(ticks - 1u);
  uint16_t least = (uint16_t)(TCNT1 + HAL_STEP_MARGIN);  // TCNT1 is small here: just past a match
  OCR1A = top > least ? top : least;
}

// Also called from the main loop: the two single-byte writes stop the timer whatever interrupts.
HAL_INLINE void hal_step_timer_stop(void) {
  TIMSK1 = 0;
  TCCR1B = 0;
}

// STEP/DIR writes run inside the step ISR (or with interrupts off), so the read-modify-write of PORTL is safe.
HAL_INLINE void hal_step_high(uint8_t mask) {
  if (mask & 0x01) HAL_SET(RBX1_J1_STEP);
  if (mask & 0x02) HAL_SET(RBX1_J2_STEP);
  if (mask & 0x04) HAL_SET(RBX1_J3_STEP);
  if (mask & 0x08) HAL_SET(RBX1_J4_STEP);
  if (mask & 0x10) HAL_SET(RBX1_J5_STEP);
  if (mask & 0x20) HAL_SET(RBX1_J6_STEP);
}

// The STEP bits of the pin map that sit on port c: one read-modify-write per port instead of one per pin.
#define HAL_STEP_BITS(c) (uint8_t)(                                                                 \
  (RBX1_J1_STEP_PORT == (c) ? 1u << RBX1_J1_STEP_BIT : 0u) | (RBX1_J2_STEP_PORT == (c) ? 1u << RBX1_J2_STEP_BIT : 0u) | \
  (RBX1_J3_STEP_PORT == (c) ? 1u << RBX1_J3_STEP_BIT : 0u) | (RBX1_J4_STEP_PORT == (c) ? 1u << RBX1_J4_STEP_BIT : 0u) | \
  (RBX1_J5_STEP_PORT == (c) ? 1u << RBX1_J5_STEP_BIT : 0u) | (RBX1_J6_STEP_PORT == (c) ? 1u << RBX1_J6_STEP_BIT : 0u))
#define HAL_STEP_CLR_PORT(c) do { if (HAL_STEP_BITS(c)) HAL_PORT(c) &= (uint8_t)~HAL_STEP_BITS(c); } while (0)

HAL_INLINE void hal_step_low(void) {
  HAL_STEP_CLR_PORT('A'); HAL_STEP_CLR_PORT('B'); HAL_STEP_CLR_PORT('C'); HAL_STEP_CLR_PORT('D');
  HAL_STEP_CLR_PORT('E'); HAL_STEP_CLR_PORT('F'); HAL_STEP_CLR_PORT('G'); HAL_STEP_CLR_PORT('H');
  HAL_STEP_CLR_PORT('J'); HAL_STEP_CLR_PORT('K'); HAL_STEP_CLR_PORT('L');
}

HAL_INLINE void hal_dir_write(uint8_t positive) {
  uint8_t m = RBX1_DIR_POSITIVE_LEVEL ? positive : (uint8_t)~positive;
  HAL_WRITE(RBX1_J1_DIR, m & 0x01);
  HAL_WRITE(RBX1_J2_DIR, m & 0x02);
  HAL_WRITE(RBX1_J3_DIR, m & 0x04);
  HAL_WRITE(RBX1_J4_DIR, m & 0x08);
  HAL_WRITE(RBX1_J5_DIR, m & 0x10);
  HAL_WRITE(RBX1_J6_DIR, m & 0x20);
}

HAL_INLINE uint8_t hal_limit_inputs(void) {
  uint8_t m = (uint8_t)(HAL_READ(RBX1_J1_LIMIT) | (HAL_READ(RBX1_J2_LIMIT) << 1) | (HAL_READ(RBX1_J3_LIMIT) << 2) |
                        (HAL_READ(RBX1_J4_LIMIT) << 3) | (HAL_READ(RBX1_J5_LIMIT) << 4) |
                        (HAL_READ(RBX1_J6_LIMIT) << 5));
  return RBX1_LIMIT_TRIGGERED_LEVEL ? m : (uint8_t)(~m & RBX1_ALL_JOINTS_MASK);
}

HAL_INLINE uint8_t hal_estop_input(void) {
  return (uint8_t)(HAL_READ(RBX1_ESTOP) == RBX1_ESTOP_ASSERTED_LEVEL);
}

#endif
#endif

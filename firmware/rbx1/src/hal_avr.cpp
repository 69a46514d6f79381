// hal_avr.cpp - the HAL on the ATmega2560: Timer1 step interrupt, Timer3 1 kHz profile tick (also the millisecond
// clock), Timer4 servo PWM, UART0 with its own lean interrupts and ring buffers, EEPROM, watchdog. The only file
// (with hal_avr.h) that touches registers. The Arduino core's Serial and its Timer0 tick are not used: their
// interrupts keep interrupts off up to 148 and 112 cycles, ours at most the figures in firmware/README.md, Timing.
#ifdef __AVR__

#include <Arduino.h>  // the core still starts the chip (init()) and calls setup()/loop()
#include <avr/eeprom.h>
#include <avr/wdt.h>

#include "config.h"
#include "hal.h"
#include "pins.h"
#include "stepper.h"

#if F_CPU != 16000000UL
#error "the timer set-up below assumes a 16 MHz ATmega2560"
#endif

// MCUSR survives only if read before anything else: .init3 runs before main() and the C++ constructors.
// The watchdog stays armed after a watchdog reset, so it is disabled here until hal_init() re-arms it.
static uint8_t mcusr_at_boot __attribute__((section(".noinit")));
extern "C" void hal_read_mcusr(void) __attribute__((naked, used, section(".init3")));
extern "C" void hal_read_mcusr(void) {
  mcusr_at_boot = MCUSR;
  MCUSR = 0;
  wdt_disable();
}

#define OUTPUT_PIN(sig) (HAL_DDR(sig##_PORT) |= (uint8_t)(1u << sig##_BIT))
#define INPUT_PULLUP_PIN(sig) \
  do { HAL_DDR(sig##_PORT) &= (uint8_t)~(1u << sig##_BIT); HAL_SET(sig); } while (0)

// No interrupts-off window: the Arduino core's Timer0 tick, the only interrupt enabled before this, goes first;
// every other interrupt source starts disabled, so nothing can run in between.
void hal_init(void) {
  TIMSK0 = 0;  // the Arduino core's millis() tick is not used (the profile tick counts milliseconds)
  hal_drivers_enable(0);  // EN high before the pins become outputs
  OUTPUT_PIN(RBX1_J1_EN); OUTPUT_PIN(RBX1_J2_EN); OUTPUT_PIN(RBX1_J3_EN);
  OUTPUT_PIN(RBX1_J4_EN); OUTPUT_PIN(RBX1_J5_EN); OUTPUT_PIN(RBX1_J6_EN);
  hal_step_low();
  OUTPUT_PIN(RBX1_J1_STEP); OUTPUT_PIN(RBX1_J2_STEP); OUTPUT_PIN(RBX1_J3_STEP);
  OUTPUT_PIN(RBX1_J4_STEP); OUTPUT_PIN(RBX1_J5_STEP); OUTPUT_PIN(RBX1_J6_STEP);
  OUTPUT_PIN(RBX1_J1_DIR); OUTPUT_PIN(RBX1_J2_DIR); OUTPUT_PIN(RBX1_J3_DIR);
  OUTPUT_PIN(RBX1_J4_DIR); OUTPUT_PIN(RBX1_J5_DIR); OUTPUT_PIN(RBX1_J6_DIR);
  INPUT_PULLUP_PIN(RBX1_J1_LIMIT); INPUT_PULLUP_PIN(RBX1_J2_LIMIT); INPUT_PULLUP_PIN(RBX1_J3_LIMIT);
  INPUT_PULLUP_PIN(RBX1_J4_LIMIT); INPUT_PULLUP_PIN(RBX1_J5_LIMIT); INPUT_PULLUP_PIN(RBX1_J6_LIMIT);
  INPUT_PULLUP_PIN(RBX1_ESTOP);
  HAL_CLR(RBX1_SERVO);
  OUTPUT_PIN(RBX1_SERVO);

  // Timer1: step timer, CTC on OCR1A, clock stopped until hal_step_timer_start().
  TCCR1A = 0;
  TCCR1B = 0;
  TIMSK1 = 0;
  // Timer3: profile tick, CTC at F_CPU/8/2000 = 1 kHz.
  TCCR3A = 0;
  TCCR3B = (uint8_t)((1 << WGM32) | (1 << CS31));
  OCR3A = (uint16_t)(F_CPU / 8 / PROFILE_TICK_HZ - 1);
  TCNT3 = 0;
  TIMSK3 = (uint8_t)(1 << OCIE3A);
  // Timer4: servo, fast PWM with TOP = ICR4 = 20 ms at 2 MHz; OC4A connected on the first pulse.
  TCCR4A = (uint8_t)(1 << WGM41);
  TCCR4B = (uint8_t)((1 << WGM43) | (1 << WGM42) | (1 << CS41));
  ICR4 = 39999;
  OCR4A = 0;
  // UART0: 8N1 at SERIAL_BAUD with double speed (the Arduino core's divisor: 2.1% fast at 115200).
  UCSR0B = 0;
  UCSR0A = (uint8_t)(1 << U2X0);
  UBRR0 = (uint16_t)((F_CPU / 4 / SERIAL_BAUD - 1) / 2);
  UCSR0C = (uint8_t)((1 << UCSZ01) | (1 << UCSZ00));
  UCSR0B = (uint8_t)((1 << RXEN0) | (1 << TXEN0) | (1 << RXCIE0));
  wdt_enable(WDTO_500MS);
}

// Milliseconds: counted by the profile tick. Written only there, read here with interrupts off (4 bytes).
static volatile uint32_t ms_count;

uint32_t hal_millis(void) {
  uint8_t s = SREG;
  cli();
  uint32_t m = ms_count;
  SREG = s;
  return m;
}

// UART0 ring buffers: one producer and one consumer each, 8-bit indices (the receive side wraps for free at 256).
// A byte arriving when the receive buffer is full is dropped (the protocol's CRC and retransmission recover).
#define TX_SIZE 128u
static volatile uint8_t rx_buf[256];
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t tx_buf[TX_SIZE];
static volatile uint8_t tx_head, tx_tail;

ISR(USART0_RX_vect) {
  uint8_t c = UDR0;
  uint8_t h = rx_head;
  uint8_t next = (uint8_t)(h + 1u);
  if (next != rx_tail) {
    rx_buf[h] = c;
    rx_head = next;
  }
}

ISR(USART0_UDRE_vect) {
  uint8_t t = tx_tail;
  if (t == tx_head) {
    UCSR0B = (uint8_t)(UCSR0B & ~(1 << UDRIE0));  // nothing left: this interrupt only runs inside UART0 code
    return;
  }
  UDR0 = tx_buf[t];
  tx_tail = (uint8_t)((t + 1u) & (TX_SIZE - 1u));
}

int16_t hal_serial_read(void) {
  uint8_t t = rx_tail;
  if (t == rx_head) {
    // Idle: read the status register as a polling loop would. Harmless on the chip; simavr's UART model takes
    // more input from its pty only after such a read finds its FIFO empty (its XON), so without it a burst that
    // once filled that FIFO would stop reception for good under rbx1-avrsim.
    (void)UCSR0A;
    return -1;
  }
  uint8_t c = rx_buf[t];
  rx_tail = (uint8_t)(t + 1u);
  return c;
}

void hal_serial_write(const uint8_t *data, uint8_t n) {
  for (uint8_t i = 0; i < n; i++) {
    uint8_t h = tx_head;
    uint8_t next = (uint8_t)((h + 1u) & (TX_SIZE - 1u));
    while (next == tx_tail) {
    }  // full: the UDRE interrupt drains it
    tx_buf[h] = data[i];
    tx_head = next;
    uint8_t s = SREG;
    cli();  // UCSR0B has no atomic bit instructions and the UDRE interrupt clears UDRIE0
    UCSR0B = (uint8_t)(UCSR0B | (1 << UDRIE0));
    SREG = s;
  }
}

void hal_step_timer_start(uint16_t ticks) {
  uint8_t s = SREG;
  cli();
  TCCR1B = 0;
  TCNT1 = 0;
  OCR1A = (uint16_t)(ticks - 1u);
  TIFR1 = (uint8_t)(1 << OCF1A);  // drop a stale compare flag
  TIMSK1 = (uint8_t)(1 << OCIE1A);
  TCCR1B = (uint8_t)((1 << WGM12) | (1 << CS11));
  SREG = s;
}

void hal_drivers_enable(uint8_t on) {
  uint8_t s = SREG;
  cli();  // EN of J3 sits on PORTK, which has no atomic bit instructions
  uint8_t level = on ? RBX1_EN_ACTIVE_LEVEL : !RBX1_EN_ACTIVE_LEVEL;
  HAL_WRITE(RBX1_J1_EN, level); HAL_WRITE(RBX1_J2_EN, level); HAL_WRITE(RBX1_J3_EN, level);
  HAL_WRITE(RBX1_J4_EN, level); HAL_WRITE(RBX1_J5_EN, level); HAL_WRITE(RBX1_J6_EN, level);
  SREG = s;
}

void hal_servo_write(uint16_t pulse_us) {
  uint8_t s = SREG;
  cli();  // 16-bit register write
  if (pulse_us == 0) {
    TCCR4A = (uint8_t)(1 << WGM41);
    HAL_CLR(RBX1_SERVO);
  } else {
    OCR4A = (uint16_t)(pulse_us * 2u);
    TCCR4A = (uint8_t)((1 << WGM41) | (1 << COM4A1));
  }
  SREG = s;
}

uint8_t hal_eeprom_read(uint16_t addr) { return eeprom_read_byte((const uint8_t *)addr); }

void hal_eeprom_write(uint16_t addr, uint8_t value) { eeprom_update_byte((uint8_t *)addr, value); }

void hal_watchdog_kick(void) { wdt_reset(); }

uint8_t hal_reset_by_watchdog(void) { return (mcusr_at_boot & (1 << WDRF)) != 0; }

hal_irq_state hal_irq_save(void) {
  uint8_t s = SREG;
  cli();
  return s;
}

void hal_irq_restore(hal_irq_state s) { SREG = s; }

void hal_entry_done(uint8_t, uint16_t, const int32_t *, const int32_t *, const int32_t *, uint16_t, uint16_t) {}

uint16_t hal_capabilities(void) { return 0; }

ISR(TIMER1_COMPA_vect) { st_step_isr(); }

// Interruptible: the step interrupt must never wait for the profile tick's division. A tick never nests in
// itself: it takes far less than the 1 ms period.
ISR(TIMER3_COMPA_vect, ISR_NOBLOCK) {
  ms_count = ms_count + 1;
  st_profile_isr();
}

#endif

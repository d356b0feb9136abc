#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "config.h"
#include "millis.h"

static volatile uint16_t ms;

ISR(TIMER0_COMPA_vect) { ms++; }

void millis_init(void)
{
	TCCR0A = _BV(WGM01);               /* CTC */
	OCR0A = (uint8_t)(F_CPU / 64UL / 1000UL - 1UL); /* 250 counts of clk/64 = 1 ms */
	TCCR0B = _BV(CS01) | _BV(CS00);    /* clk/64 */
	TIMSK0 = _BV(OCIE0A);
}

uint16_t millis(void)
{
	uint16_t now;
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { now = ms; }
	return now;
}

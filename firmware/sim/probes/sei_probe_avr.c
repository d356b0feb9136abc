/* sei_probe_avr: how many instructions run after `sei` before a pending interrupt is taken.
 * On the ATmega328P exactly one (data sheet: the instruction after SEI is executed before
 * any pending interrupt), so the ISR sees r2 = 1, r3 = 0, r4 = 0. Build with
 *   avr-gcc -mmcu=atmega328p -Os -ffixed-r2 -ffixed-r3 -ffixed-r4 sei_probe_avr.c -o sei.elf
 * and run it with sei_probe (sei_probe.c). */
#include <avr/interrupt.h>
#include <avr/io.h>

volatile uint8_t after_sei[3]; /* r2, r3, r4 as seen by the interrupt */
volatile uint8_t taken;
register uint8_t r2 asm("r2");
register uint8_t r3 asm("r3");
register uint8_t r4 asm("r4");

ISR(INT0_vect)
{
	after_sei[0] = r2;
	after_sei[1] = r3;
	after_sei[2] = r4;
	taken = 1;
	EIMSK = 0;
}

int main(void)
{
	r2 = r3 = r4 = 0;
	DDRD |= _BV(PD2);
	EICRA = _BV(ISC00); /* INT0 on any change of PD2, also when driven by the AVR itself */
	EIMSK = _BV(INT0);
	cli();
	PORTD ^= _BV(PD2); /* the INT0 flag is set while interrupts are off */
	__asm__ volatile("sei\n\tinc r2\n\tinc r3\n\tinc r4\n\tnop\n");
	for (;;) {
	}
}

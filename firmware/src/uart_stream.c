#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "config.h"
#include "uart_stream.h"

#define QUEUE_SIZE 128 /* a power of two; four 200 Hz lines */

static char queue[QUEUE_SIZE];
static volatile uint8_t head; /* next byte to send */
static volatile uint8_t tail; /* next free slot */

void uart_init(void)
{
	/* Double speed: 16 MHz / (8 * (16 + 1)) = 117647 baud, 2.1 % from 115200. */
	UCSR0A = _BV(U2X0);
	UBRR0 = (uint16_t)((F_CPU / (8UL * BMG_UART_BAUD)) - 1UL);
	UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
	UCSR0B = _BV(TXEN0);
}

ISR(USART_UDRE_vect)
{
	if (head == tail) {
		UCSR0B &= (uint8_t)~_BV(UDRIE0);
		return;
	}
	UDR0 = queue[head];
	head = (uint8_t)((head + 1) & (QUEUE_SIZE - 1));
}

uint8_t uart_room(void)
{
	return (uint8_t)(QUEUE_SIZE - 2 - ((tail - head) & (QUEUE_SIZE - 1)));
}

uint8_t uart_send_line(const char *line, uint8_t length)
{
	uint8_t used = (uint8_t)((tail - head) & (QUEUE_SIZE - 1));
	if (length >= QUEUE_SIZE - 1 - used)
		return 0;
	for (uint8_t i = 0; i < length; i++) {
		queue[tail] = line[i];
		tail = (uint8_t)((tail + 1) & (QUEUE_SIZE - 1));
	}
	UCSR0B |= _BV(UDRIE0);
	return 1;
}

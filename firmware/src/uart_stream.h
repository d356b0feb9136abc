/* The sample stream on the UART, as the paper's device had (line format in
 * docs/firmware.md): interrupt-driven transmit queue, lines dropped whole when
 * the queue is full so the sample index shows every gap. */
#ifndef BMG_UART_STREAM_H
#define BMG_UART_STREAM_H
#include <stdint.h>

void uart_init(void);
/* Queue a whole line; returns 0 (and sends nothing) if it does not fit. */
uint8_t uart_send_line(const char *line, uint8_t length);
/* Bytes a line may use now (so a line that cannot fit is not even formatted). */
uint8_t uart_room(void);

#endif

/* A millisecond counter on Timer0 (for the self-test duration). */
#ifndef BMG_MILLIS_H
#define BMG_MILLIS_H
#include <stdint.h>

void millis_init(void);
uint16_t millis(void);

#endif

/* I2C slave on the ATmega328P TWI unit, driven by its interrupt. */
#ifndef BMG_TWI_SLAVE_H
#define BMG_TWI_SLAVE_H
#include <stdint.h>

void twi_slave_init(uint8_t address7);
/* True while a transaction addressed to us is in progress. */
uint8_t twi_busy(void);
/* Called by the TWI interrupt when a transaction ends (STOP or NACKed read). */
void twi_transaction_ended(void);

#endif

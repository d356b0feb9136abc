/* twi_probe: drive the firmware through simavr's own TWI slave path (TWI_IRQ_INPUT messages)
 * and print the status codes and output messages the model produces. It shows the defects
 * of Debian's simavr 1.6 that bmg160_sim.c works around (docs/firmware.md):
 *   START + SLA+W is reported as 0x80 (data received) instead of 0x60,
 *   STOP is reported as 0xA8 instead of 0xA0,
 *   after SLA+R (0xA8) the master's ACKs produce no 0xB8: slave transmit ends after one byte.
 * Usage: twi_probe FIRMWARE.elf   (build: make probe BUILD_DIR=...) */
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include "avr_twi.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"
static avr_t *avr;
static void no_sleep(avr_t *a, avr_cycle_count_t h) { (void)a; (void)h; }
static void on_status(struct avr_irq_t *irq, uint32_t v, void *p) { (void)irq; (void)p; printf("  status %02x\n", v); }
static void on_out(struct avr_irq_t *irq, uint32_t v, void *p) {
	(void)irq; (void)p; avr_twi_msg_irq_t m; m.u.v = v;
	printf("  output msg=%02x addr=%02x data=%02x\n", m.u.twi.msg, m.u.twi.addr, m.u.twi.data); }
static void run(unsigned long n) { avr_cycle_count_t t = avr->cycle + n; while (avr->cycle < t) avr_run(avr); }
int main(int argc, char **argv) {
	elf_firmware_t fw; memset(&fw, 0, sizeof fw); elf_read_firmware(argv[1], &fw);
	avr = avr_make_mcu_by_name("atmega328p"); avr_init(avr); avr_load_firmware(avr, &fw);
	avr->frequency = 16000000; avr->sleep = no_sleep; avr->log = 0;
	avr_irq_t *in = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS), on_status, 0);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT), on_out, 0);
	run(1600000);
	printf("write transaction: START+SLA+W\n");
	avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_START | TWI_COND_ADDR | TWI_COND_WRITE, 0x68, 0)); run(20000);
	printf("data 0x1B\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_WRITE, 0x68, 0x1B)); run(20000);
	printf("data 0x55\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_WRITE, 0x68, 0x55)); run(20000);
	printf("STOP\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_STOP, 0x68, 0)); run(20000);
	printf("read transaction: START+SLA+R\n");
	avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_START | TWI_COND_ADDR, 0x68, 0)); run(20000);
	printf("master ACK\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_ACK, 0x68, 1)); run(20000);
	printf("master ACK\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_ACK, 0x68, 1)); run(20000);
	printf("STOP\n"); avr_raise_irq(in, avr_twi_irq_msg(TWI_COND_STOP, 0x68, 0)); run(20000);
	return 0;
}

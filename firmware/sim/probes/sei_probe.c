/* sei_probe: run sei_probe_avr in simavr and print how many instructions ran after `sei`
 * before the pending interrupt (1 on silicon; Debian's simavr 1.6 gives 2).
 * Usage: sei_probe sei.elf */
#include <stdio.h>
#include <string.h>

#include "sim_avr.h"
#include "sim_elf.h"

int main(int argc, char **argv)
{
	elf_firmware_t fw;
	if (argc != 2) {
		fprintf(stderr, "usage: sei_probe sei.elf\n");
		return 2;
	}
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(argv[1], &fw))
		return 2;
	avr_t *avr = avr_make_mcu_by_name("atmega328p");
	avr_init(avr);
	avr_load_firmware(avr, &fw);
	avr->frequency = 16000000;
	avr->log = 0;
	for (int i = 0; i < 100000; i++)
		avr_run(avr);
	/* after_sei[3] is the first object in .bss (0x100, see avr-nm), then taken (0x103) */
	if (avr->data[0x103] != 1) {
		fprintf(stderr, "the interrupt was not taken\n");
		return 1;
	}
	int count = avr->data[0x100] + avr->data[0x101] + avr->data[0x102];
	printf("instructions executed after sei before the interrupt: %d (1 on silicon)\n", count);
	return 0;
}

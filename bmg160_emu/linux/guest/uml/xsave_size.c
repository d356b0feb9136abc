// SPDX-License-Identifier: GPL-2.0
/*
 * Print the size in bytes of this CPU's XSAVE area for the features the host kernel enabled
 * (CPUID leaf 0xD, sub-leaf 0, EBX): what ptrace's NT_X86_XSTATE regset holds, and what the
 * uml engine's kernel must have room for (bmg160_emu/linux/guest/uml.py).
 */
#include <cpuid.h>
#include <stdio.h>

int main(void)
{
	unsigned int eax, ebx, ecx, edx;

	if (__get_cpuid_max(0, 0) < 0xd)
		return 1;
	__cpuid_count(0xd, 0, eax, ebx, ecx, edx);
	printf("%u\n", ebx);
	return 0;
}

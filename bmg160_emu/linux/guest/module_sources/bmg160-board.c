// SPDX-License-Identifier: GPL-2.0
/*
 * bmg160-board: declare BMG160 gyroscopes on an I2C adapter with their interrupt taken
 * from GPIO lines, as a board file or device tree would. Needed because the sysfs
 * new_device interface gives a client no IRQ, and the bmg160 driver registers its
 * data-ready trigger and events only with one.
 *
 * Parameters: bus (the adapter number), gpio_base (the global number of line 0 of the
 * GPIO controller), addr[] and line[] (one GPIO line per address; -1 for none), name (the
 * I2C device name the driver matches, "bmg160" unless given: a user's own driver's name).
 * Part of bmg160-emu (bmg160_emu/linux/guest/debian_modules.py and uml_build.py build it; docs/virtio-i2c.md).
 */
#include <linux/gpio.h>
#include <linux/i2c.h>
#include <linux/module.h>
#include <linux/string.h>

#define MAX_CHIPS 2

static int bus = -1;
module_param(bus, int, 0444);
MODULE_PARM_DESC(bus, "I2C adapter number");
static int gpio_base = -1;
module_param(gpio_base, int, 0444);
MODULE_PARM_DESC(gpio_base, "global GPIO number of line 0 of the interrupt controller");
static int addr[MAX_CHIPS] = { 0x68 };
static int n_addr = 1;
module_param_array(addr, int, &n_addr, 0444);
MODULE_PARM_DESC(addr, "7-bit addresses of the chips");
static int line[MAX_CHIPS] = { -1, -1 };
static int n_line;
module_param_array(line, int, &n_line, 0444);
MODULE_PARM_DESC(line, "GPIO line of each chip's interrupt (INT1), -1 for none");

static char *name = "bmg160";
module_param(name, charp, 0444);
MODULE_PARM_DESC(name, "I2C device name of the chips (the driver's id table entry)");

static struct i2c_client *clients[MAX_CHIPS];

static int __init bmg160_board_init(void)
{
	struct i2c_adapter *adapter;
	int i, ret = 0;

	adapter = i2c_get_adapter(bus);
	if (!adapter) {
		pr_err("bmg160-board: no I2C adapter %d\n", bus);
		return -ENODEV;
	}
	for (i = 0; i < n_addr; i++) {
		struct i2c_board_info info = { I2C_BOARD_INFO("bmg160", addr[i]) };

		strscpy(info.type, name, sizeof(info.type));
		if (i < n_line && line[i] >= 0) {
			if (gpio_base < 0) {
				ret = -EINVAL;
				break;
			}
			info.irq = gpio_to_irq(gpio_base + line[i]);
			if (info.irq < 0) {
				ret = info.irq;
				pr_err("bmg160-board: GPIO %d has no IRQ: %d\n", gpio_base + line[i], ret);
				break;
			}
		}
		clients[i] = i2c_new_client_device(adapter, &info);
		if (IS_ERR(clients[i])) {
			ret = PTR_ERR(clients[i]);
			clients[i] = NULL;
			break;
		}
		pr_info("bmg160-board: %s at %d-%04x, irq %d\n", name, bus, addr[i], info.irq);
	}
	i2c_put_adapter(adapter);
	if (ret) {
		while (--i >= 0)
			i2c_unregister_device(clients[i]);
	}
	return ret;
}

static void __exit bmg160_board_exit(void)
{
	int i;

	for (i = 0; i < MAX_CHIPS; i++)
		i2c_unregister_device(clients[i]);
}

module_init(bmg160_board_init);
module_exit(bmg160_board_exit);
MODULE_DESCRIPTION("BMG160 gyroscopes with interrupt lines on an I2C adapter (bmg160-emu)");
MODULE_LICENSE("GPL");

// SPDX-License-Identifier: GPL-2.0
/*
 * gyro_chipid: a minimal I2C driver standing in for "your driver" in bmg160-emu's kernel
 * harness (docs/kernel-test.md). On probe it reads the chip's CHIP_ID register (0x00; the
 * BMG160 answers 0x0F) and refuses other chips; the value is the read-only sysfs attribute
 * chip_id of the I2C client, and rate_x reads the X rate registers (0x02, 0x03) on demand.
 */
#include <linux/i2c.h>
#include <linux/module.h>

#define GYRO_REG_CHIP_ID	0x00
#define GYRO_REG_RATE_X_LSB	0x02
#define GYRO_CHIP_ID		0x0f

static ssize_t chip_id_show(struct device *dev, struct device_attribute *attr, char *buf)
{
	int id = i2c_smbus_read_byte_data(to_i2c_client(dev), GYRO_REG_CHIP_ID);

	if (id < 0)
		return id;
	return sysfs_emit(buf, "0x%02x\n", id);
}
static DEVICE_ATTR_RO(chip_id);

static ssize_t rate_x_show(struct device *dev, struct device_attribute *attr, char *buf)
{
	u8 raw[2];
	int ret = i2c_smbus_read_i2c_block_data(to_i2c_client(dev), GYRO_REG_RATE_X_LSB,
						sizeof(raw), raw);

	if (ret < 0)
		return ret;
	if (ret != sizeof(raw))
		return -EIO;
	return sysfs_emit(buf, "%d\n", (s16)(raw[0] | raw[1] << 8));
}
static DEVICE_ATTR_RO(rate_x);

static struct attribute *gyro_chipid_attrs[] = {
	&dev_attr_chip_id.attr,
	&dev_attr_rate_x.attr,
	NULL
};
ATTRIBUTE_GROUPS(gyro_chipid);

static int gyro_chipid_probe(struct i2c_client *client)
{
	int id = i2c_smbus_read_byte_data(client, GYRO_REG_CHIP_ID);

	if (id < 0)
		return id;
	if (id != GYRO_CHIP_ID) {
		dev_err(&client->dev, "chip id 0x%02x, expected 0x%02x\n", id, GYRO_CHIP_ID);
		return -ENODEV;
	}
	dev_info(&client->dev, "gyro_chipid: chip id 0x%02x\n", id);
	return 0;
}

static const struct i2c_device_id gyro_chipid_id[] = {
	{ "gyro_chipid", 0 },
	{ }
};
MODULE_DEVICE_TABLE(i2c, gyro_chipid_id);

static struct i2c_driver gyro_chipid_driver = {
	.driver = {
		.name = "gyro_chipid",
		.dev_groups = gyro_chipid_groups,
	},
	.probe_new = gyro_chipid_probe,
	.id_table = gyro_chipid_id,
};
module_i2c_driver(gyro_chipid_driver);

MODULE_DESCRIPTION("Reads a BMG160's chip ID (bmg160-emu's stand-in for a user's driver)");
MODULE_LICENSE("GPL");

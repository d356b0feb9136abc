/* SPDX-License-Identifier: MIT
 *
 * The guest's agent (bmg160_emu.linux.guest.agent): one static program that is PID 1 of a
 * user-mode Linux guest (it mounts, loads the modules, finds the virtio adapters) and then
 * serves the host's requests: run a shell command, read or write a file (sysfs attributes),
 * load or unload a module, wait for a path, list a glob, read an IIO buffer; a batch of
 * these per request. No shell and no Python run unless a request asks for one: under UML
 * every guest system call is a ptrace stop and a fork+exec costs 15-25 ms, where a sysfs
 * read from this process costs 0.16 ms (linux-kernel-notes.md).
 *
 * The channel: two lines of the virtio-gpio controller the host serves. The host writes the
 * request into FOLDER/request, then pulses the request line (a rising edge, read here from
 * the line's event file descriptor: no polling); the agent answers in FOLDER/response and
 * toggles the reply line (a SET_VALUE request the host sees at once). Under time travel
 * both are events of the host's calendar, so the guest never waits on the host's clock.
 *
 * Modes:
 *   agent (as PID 1)                  UML init: settings from the kernel command line
 *                                     (guest_* words; upper-case KEY=VAL for commands)
 *   agent serve FOLDER REQ REPLY      serve on lines REQ and REPLY of the virtio-gpio chip
 *                                     (the QEMU engine's boot script runs this); "fifo fifo":
 *                                     on FOLDER/request.fifo and reply.fifo (tests, no kernel)
 *   agent orphan-guard PPID -- CMD    run CMD in a process group of its own, ended with it
 *                                     and when the parent PPID ends (on the host: a guest
 *                                     and its helper processes do not outlive the harness)
 *
 * The wire format of both files: a header line "BGQ1 SEQ COUNT" (request) or "BGR1 SEQ
 * COUNT" (response), then COUNT records "NAME FLAGS NFIELDS" (request) or "STATUS NFIELDS"
 * (response), each followed by NFIELDS fields written as "LENGTH\n" + bytes + "\n".
 */
#define _GNU_SOURCE
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <fnmatch.h>
#include <glob.h>
#include <linux/gpio.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mount.h>
#include <sys/prctl.h>
#include <sys/reboot.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_FIELDS 8
#define MAX_ENV 96
#define CHECK 1 /* request flag: skip the rest of the batch when this one fails */
#define SKIPPED (-1)

static char *environment[MAX_ENV + 1];
static int env_count;
static char modroot[4096], release[128];
static char bus_text[16], gpio_base_text[16];

static void say(const char *format, ...)
{
	va_list args;

	va_start(args, format);
	fputs("agent: ", stderr);
	vfprintf(stderr, format, args);
	fputc('\n', stderr);
	va_end(args);
}

static void env_add(const char *key, const char *value)
{
	char *word;

	if (env_count >= MAX_ENV || asprintf(&word, "%s=%s", key, value) < 0)
		return;
	environment[env_count++] = word;
	environment[env_count] = NULL;
}

static int64_t now_ns(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static void sleep_ns(int64_t ns)
{
	struct timespec t = { ns / 1000000000, ns % 1000000000 };

	while (nanosleep(&t, &t) < 0 && errno == EINTR)
		;
}

/* ---------------------------------------------------------------- files */

/* The whole file at path (NUL-terminated, its length in *length), or NULL with errno set. */
static char *read_file(const char *path, size_t limit, size_t *length)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	size_t size = 0, room = 4096;
	char *data;
	ssize_t got;

	if (fd < 0)
		return NULL;
	data = malloc(room + 1);
	while (data && size < limit) {
		if (size == room) {
			char *bigger = realloc(data, 2 * room + 1);

			if (!bigger) {
				free(data);
				data = NULL;
				break;
			}
			data = bigger;
			room *= 2;
		}
		got = read(fd, data + size, (room - size < limit - size ? room - size : limit - size));
		if (got < 0 && errno == EINTR)
			continue;
		if (got < 0) {
			int saved = errno;

			free(data);
			close(fd);
			errno = saved;
			return NULL;
		}
		if (got == 0)
			break;
		size += got;
	}
	close(fd);
	if (!data) {
		errno = ENOMEM;
		return NULL;
	}
	data[size] = 0;
	if (length)
		*length = size;
	return data;
}

static int write_all(int fd, const char *data, size_t length)
{
	while (length) {
		ssize_t done = write(fd, data, length);

		if (done < 0 && errno == EINTR)
			continue;
		if (done < 0)
			return -1;
		data += done;
		length -= done;
	}
	return 0;
}

/* Write data to path in one write(2) (what a sysfs attribute wants); 0 or an errno. */
static int write_file(const char *path, const char *data, size_t length, int flags)
{
	int fd = open(path, O_WRONLY | O_CLOEXEC | flags, 0644);
	int status = 0;

	if (fd < 0)
		return errno;
	if (write_all(fd, data, length) < 0)
		status = errno;
	if (close(fd) < 0 && !status)
		status = errno;
	return status;
}

/* ---------------------------------------------------------------- modules */

static int load_module_file(const char *path, const char *params)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	int status = 0;

	if (fd < 0)
		return errno;
	if (syscall(SYS_finit_module, fd, params ? params : "", 0) < 0 && errno != EEXIST)
		status = errno;
	close(fd);
	return status;
}

static void module_name_of(const char *path, char *name, size_t room)
{
	const char *base = strrchr(path, '/');
	size_t i;

	base = base ? base + 1 : path;
	for (i = 0; base[i] && i + 1 < room; i++)
		name[i] = base[i] == '-' ? '_' : base[i];
	name[i] = 0;
	if (i > 3 && !strcmp(name + i - 3, ".ko"))
		name[i - 3] = 0;
}

/* The line of a modules.* file of this kernel whose module (or alias) matches; NULL if none. */
static char *modules_file(const char *which)
{
	char path[4300];

	snprintf(path, sizeof(path), "%s/lib/modules/%s/%s", modroot, release, which);
	return read_file(path, 64 << 20, NULL);
}

/* Resolve an alias (i2c:bmg160) to its module's name through modules.alias. */
static int resolve_alias(const char *alias, char *name, size_t room)
{
	char *table = modules_file("modules.alias"), *line, *save;
	int found = 0;

	if (!table)
		return 0;
	for (line = strtok_r(table, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
		char pattern[512], module[256];

		if (sscanf(line, "alias %511s %255s", pattern, module) == 2 &&
		    !fnmatch(pattern, alias, 0)) {
			module_name_of(module, name, room);
			found = 1;
			break;
		}
	}
	free(table);
	return found;
}

static int is_builtin(const char *name)
{
	char *table = modules_file("modules.builtin"), *line, *save;
	int found = 0;

	if (!table)
		return 0;
	for (line = strtok_r(table, "\n", &save); line && !found; line = strtok_r(NULL, "\n", &save)) {
		char other[256];

		module_name_of(line, other, sizeof(other));
		found = !strcmp(other, name);
	}
	free(table);
	return found;
}

/* modprobe: NAME (or an alias) with the modules it depends on, from modules.dep. */
static int modprobe(const char *wanted, const char *params)
{
	char name[256], *table, *line, *save;
	int status = ENOENT;
	size_t i;

	for (i = 0; wanted[i] && i + 1 < sizeof(name); i++)
		name[i] = wanted[i] == '-' ? '_' : wanted[i];
	name[i] = 0;
	if (strchr(wanted, ':') && !resolve_alias(wanted, name, sizeof(name)))
		return ENOENT;
	if (is_builtin(name))
		return 0;
	table = modules_file("modules.dep");
	if (!table)
		return errno;
	for (line = strtok_r(table, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
		char *colon = strchr(line, ':'), other[256], *deps[64], *word, *wsave;
		int count = 0, k;

		if (!colon)
			continue;
		*colon = 0;
		module_name_of(line, other, sizeof(other));
		if (strcmp(other, name))
			continue;
		for (word = strtok_r(colon + 1, " ", &wsave); word && count < 64;
		     word = strtok_r(NULL, " ", &wsave))
			deps[count++] = word;
		status = 0;
		/* modules.dep lists the deepest dependency last: load from the end */
		for (k = count - 1; k >= 0 && !status; k--) {
			char path[4600];

			snprintf(path, sizeof(path), "%s/lib/modules/%s/%s", modroot, release, deps[k]);
			status = load_module_file(path, "");
		}
		if (!status) {
			char path[4600];

			snprintf(path, sizeof(path), "%s/lib/modules/%s/%s", modroot, release, line);
			status = load_module_file(path, params);
		}
		break;
	}
	free(table);
	return status;
}

/* ---------------------------------------------------------------- requests */

struct field {
	char *data;
	size_t length;
};

struct answer {
	int status;
	int count;
	struct field fields[MAX_FIELDS];
	int owned[MAX_FIELDS];
};

static void answer_text(struct answer *a, const char *format, ...)
{
	va_list args;
	char *text;
	int n;

	va_start(args, format);
	n = vasprintf(&text, format, args);
	va_end(args);
	if (n < 0 || a->count >= MAX_FIELDS)
		return;
	a->fields[a->count].data = text;
	a->fields[a->count].length = n;
	a->owned[a->count++] = 1;
}

static void answer_data(struct answer *a, char *data, size_t length)
{
	if (a->count >= MAX_FIELDS) {
		free(data);
		return;
	}
	a->fields[a->count].data = data;
	a->fields[a->count].length = length;
	a->owned[a->count++] = 1;
}

static void reap(void)
{
	while (waitpid(-1, NULL, WNOHANG) > 0)
		;
}

/* run CWD COMMAND OUT ERR: /bin/sh -c COMMAND with stdout and stderr in the files named. */
static void op_run(struct field *f, int n, struct answer *a)
{
	pid_t child, done;
	int status;

	if (n != 4) {
		a->status = EINVAL;
		return;
	}
	child = fork();
	if (child < 0) {
		a->status = errno;
		return;
	}
	if (child == 0) {
		int in = open("/dev/null", O_RDONLY);
		int out = open(f[2].data, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		int err = open(f[3].data, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		sigset_t none;

		sigemptyset(&none);
		sigprocmask(SIG_SETMASK, &none, NULL);
		signal(SIGCHLD, SIG_DFL);
		setsid();
		if (in < 0 || out < 0 || err < 0)
			_exit(126);
		dup2(in, 0);
		dup2(out, 1);
		dup2(err, 2);
		if (chdir(f[0].data) < 0 && chdir("/") < 0)
			_exit(126);
		execle("/bin/sh", "sh", "-c", f[1].data, (char *)NULL, environment);
		_exit(127);
	}
	do
		done = waitpid(child, &status, 0);
	while (done < 0 && errno == EINTR);
	if (done < 0) {
		a->status = errno;
		return;
	}
	answer_text(a, "%d", WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status));
}

/* capture DEVICE OUT MAX_RECORDS RECORD_SIZE TIMEOUT_NS: read an IIO buffer into OUT until
 * MAX_RECORDS records (0: no limit) or TIMEOUT_NS of the guest's clock have passed, then
 * drain what the watermark held back. Ends by itself: i2c-virtio (6.1) must not see the
 * reader killed while the driver talks to the bus on its behalf. */
static void op_capture(struct field *f, int n, struct answer *a)
{
	long long records, size, timeout, wanted, got = 0;
	int64_t start, end;
	int fd, out;
	char *buffer;

	if (n != 5) {
		a->status = EINVAL;
		return;
	}
	records = atoll(f[2].data);
	size = atoll(f[3].data);
	timeout = atoll(f[4].data);
	if (size <= 0 || size > 4096) {
		a->status = EINVAL;
		return;
	}
	fd = open(f[0].data, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
	if (fd < 0) {
		a->status = errno;
		return;
	}
	out = open(f[1].data, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
	buffer = malloc(512 * size);
	if (out < 0 || !buffer) {
		a->status = out < 0 ? errno : ENOMEM;
		close(fd);
		free(buffer);
		return;
	}
	start = now_ns();
	end = timeout > 0 ? start + timeout : INT64_MAX;
	for (;;) {
		struct pollfd p = { fd, POLLIN, 0 };
		int64_t left = end - now_ns();
		ssize_t chunk;

		if (records > 0 && got >= records)
			break;
		if (left <= 0)
			break;
		if (poll(&p, 1, left > INT32_MAX * 1000000LL ? -1 : (int)((left + 999999) / 1000000)) <= 0)
			continue;
		wanted = records > 0 && records - got < 512 ? records - got : 512;
		chunk = read(fd, buffer, wanted * size);
		if (chunk > 0) {
			write_all(out, buffer, chunk);
			got += chunk / size;
		}
	}
	while (records <= 0 || got < records) {
		wanted = records > 0 && records - got < 512 ? records - got : 512;
		ssize_t chunk = read(fd, buffer, wanted * size);

		if (chunk <= 0)
			break;
		write_all(out, buffer, chunk);
		got += chunk / size;
	}
	free(buffer);
	close(fd);
	close(out);
	answer_text(a, "%lld", got);
	answer_text(a, "%lld", (long long)(now_ns() - start));
}

static void op_glob(struct field *f, int n, struct answer *a)
{
	glob_t found;
	size_t i, length = 0;
	char *text;

	if (n != 1) {
		a->status = EINVAL;
		return;
	}
	if (glob(f[0].data, 0, NULL, &found)) {
		answer_text(a, "%s", "");
		return;
	}
	for (i = 0; i < found.gl_pathc; i++)
		length += strlen(found.gl_pathv[i]) + 1;
	text = calloc(1, length + 1);
	for (i = 0; text && i < found.gl_pathc; i++) {
		strcat(text, found.gl_pathv[i]);
		strcat(text, "\n");
	}
	globfree(&found);
	if (!text) {
		a->status = ENOMEM;
		return;
	}
	answer_data(a, text, strlen(text));
}

/* One request; 1 when it asks the agent to stop. */
static int perform(const char *name, struct field *f, int n, struct answer *a)
{
	a->status = 0;
	if (!strcmp(name, "run")) {
		op_run(f, n, a);
	} else if (!strcmp(name, "read") && n == 2) {
		size_t length;
		char *data = read_file(f[0].data, atoll(f[1].data), &length);

		if (data)
			answer_data(a, data, length);
		else
			a->status = errno;
	} else if (!strcmp(name, "write") && n == 2) {
		a->status = write_file(f[0].data, f[1].data, f[1].length, O_CREAT | O_TRUNC);
	} else if (!strcmp(name, "insmod") && n == 2) {
		a->status = load_module_file(f[0].data, f[1].data);
	} else if (!strcmp(name, "modprobe") && n == 2) {
		a->status = modprobe(f[0].data, f[1].data);
	} else if (!strcmp(name, "rmmod") && n == 1) {
		if (syscall(SYS_delete_module, f[0].data, O_NONBLOCK) < 0)
			a->status = errno;
	} else if (!strcmp(name, "wait") && n == 2) {
		int64_t end = now_ns() + atoll(f[1].data);

		while (access(f[0].data, F_OK) < 0) {
			if (now_ns() >= end) {
				a->status = ETIMEDOUT;
				break;
			}
			sleep_ns(1000000);
		}
	} else if (!strcmp(name, "glob")) {
		op_glob(f, n, a);
	} else if (!strcmp(name, "capture")) {
		op_capture(f, n, a);
	} else if (!strcmp(name, "stop")) {
		return 1;
	} else {
		a->status = EINVAL;
	}
	return 0;
}

/* A "LENGTH\n" + bytes + "\n" field at *cursor; 0 at the end of the text. */
static int take_field(char **cursor, char *end, struct field *f)
{
	char *p = *cursor, *stop;
	unsigned long long length = strtoull(p, &stop, 10);

	if (stop == p || *stop != '\n' || (size_t)(end - stop - 1) < length + 1)
		return 0;
	f->data = stop + 1;
	f->length = length;
	f->data[length] = 0; /* the separating newline becomes the NUL */
	*cursor = f->data + length + 1;
	return 1;
}

static void put_field(FILE *out, const char *data, size_t length)
{
	fprintf(out, "%zu\n", length);
	fwrite(data, 1, length, out);
	fputc('\n', out);
}

/* Serve the request in folder/request into folder/response; 1 when asked to stop. */
static int serve_one(const char *folder)
{
	char path[4200], partial[4210], *text, *cursor, *end, *line_end;
	unsigned long long seq;
	int count, i, stop = 0, skipping = 0;
	size_t length;
	FILE *out;

	snprintf(path, sizeof(path), "%s/request", folder);
	text = read_file(path, 1 << 26, &length);
	if (!text) {
		say("cannot read %s: %s", path, strerror(errno));
		return 0;
	}
	end = text + length;
	line_end = memchr(text, '\n', length);
	if (!line_end || sscanf(text, "BGQ1 %llu %d", &seq, &count) != 2 || count < 0) {
		say("%s: not a request", path);
		free(text);
		return 0;
	}
	snprintf(partial, sizeof(partial), "%s/response.tmp", folder);
	out = fopen(partial, "w");
	if (!out) {
		say("cannot write %s: %s", partial, strerror(errno));
		free(text);
		return 0;
	}
	fprintf(out, "BGR1 %llu %d\n", seq, count);
	cursor = line_end + 1;
	for (i = 0; i < count; i++) {
		char name[32];
		int flags, fields, k, ok = 1;
		struct field f[MAX_FIELDS];
		struct answer a = { 0 };

		line_end = memchr(cursor, '\n', end - cursor);
		if (!line_end || sscanf(cursor, "%31s %d %d", name, &flags, &fields) != 3 ||
		    fields < 0 || fields > MAX_FIELDS) {
			say("%s: record %d is malformed", path, i);
			break;
		}
		cursor = line_end + 1;
		for (k = 0; k < fields && ok; k++)
			ok = take_field(&cursor, end, &f[k]);
		if (!ok) {
			say("%s: record %d is cut short", path, i);
			break;
		}
		if (skipping) {
			a.status = SKIPPED;
		} else {
			stop |= perform(name, f, fields, &a);
			if (a.status && (flags & CHECK))
				skipping = 1;
		}
		fprintf(out, "%d %d\n", a.status, a.count);
		for (k = 0; k < a.count; k++) {
			put_field(out, a.fields[k].data, a.fields[k].length);
			if (a.owned[k])
				free(a.fields[k].data);
		}
	}
	free(text);
	if (fclose(out) == 0) {
		snprintf(path, sizeof(path), "%s/response", folder);
		rename(partial, path);
	}
	reap();
	return stop;
}

/* ---------------------------------------------------------------- the channel */

static int open_virtio_gpio_chip(void)
{
	DIR *dev = opendir("/dev");
	struct dirent *entry;
	int found = -1;

	while (dev && found < 0 && (entry = readdir(dev))) {
		struct gpiochip_info info;
		char path[300];
		int fd;

		if (strncmp(entry->d_name, "gpiochip", 8))
			continue;
		snprintf(path, sizeof(path), "/dev/%s", entry->d_name);
		fd = open(path, O_RDWR | O_CLOEXEC);
		if (fd < 0)
			continue;
		if (!ioctl(fd, GPIO_GET_CHIPINFO_IOCTL, &info) && !strncmp(info.label, "virtio", 6))
			found = fd;
		else
			close(fd);
	}
	if (dev)
		closedir(dev);
	return found;
}

static int request_line_fd(int chip, unsigned int offset, uint64_t flags, const char *consumer)
{
	struct gpio_v2_line_request request;

	memset(&request, 0, sizeof(request));
	request.offsets[0] = offset;
	request.num_lines = 1;
	request.config.flags = flags;
	snprintf(request.consumer, sizeof(request.consumer), "%s", consumer);
	if (ioctl(chip, GPIO_V2_GET_LINE_IOCTL, &request) < 0)
		return -1;
	return request.fd;
}

/* The channel: the virtio-gpio lines, or (line offsets "fifo") two named pipes in the
 * folder, request.fifo and reply.fifo: the host's tests of the protocol without a kernel. */
struct channel {
	int request, reply, value;
	int fifo;
};

static int channel_open(struct channel *c, const char *folder, const char *request_line,
			const char *reply_line)
{
	char path[4200];

	memset(c, 0, sizeof(*c));
	if (!strcmp(request_line, "fifo")) {
		c->fifo = 1;
		snprintf(path, sizeof(path), "%s/request.fifo", folder);
		c->request = open(path, O_RDWR | O_CLOEXEC); /* RDWR: no EOF between writers */
		snprintf(path, sizeof(path), "%s/reply.fifo", folder);
		c->reply = open(path, O_RDWR | O_CLOEXEC);
	} else {
		int chip = open_virtio_gpio_chip();

		if (chip < 0) {
			say("no virtio-gpio chip: no channel to the host");
			return -1;
		}
		c->request = request_line_fd(chip, atoi(request_line),
					     GPIO_V2_LINE_FLAG_INPUT | GPIO_V2_LINE_FLAG_EDGE_RISING,
					     "bmg160-agent-request");
		c->reply = request_line_fd(chip, atoi(reply_line), GPIO_V2_LINE_FLAG_OUTPUT,
					   "bmg160-agent-reply");
		close(chip);
	}
	if (c->request < 0 || c->reply < 0) {
		say("cannot open the channel (%s, %s): %s", request_line, reply_line, strerror(errno));
		return -1;
	}
	return 0;
}

/* Block until the host's next request; -1 when interrupted (a child ended). */
static int channel_wait(struct channel *c)
{
	struct gpio_v2_line_event event;
	char byte;
	ssize_t got = c->fifo ? read(c->request, &byte, 1) : read(c->request, &event, sizeof(event));

	if (got < 0 && errno != EINTR)
		say("reading the request channel: %s", strerror(errno));
	return got == (c->fifo ? 1 : (ssize_t)sizeof(event)) ? 0 : -1;
}

static void channel_reply(struct channel *c)
{
	struct gpio_v2_line_values values = { 0, 1 };

	c->value ^= 1;
	if (c->fifo) {
		write_all(c->reply, "r", 1);
		return;
	}
	values.bits = c->value;
	if (ioctl(c->reply, GPIO_V2_LINE_SET_VALUES_IOCTL, &values) < 0)
		say("setting the reply line: %s", strerror(errno));
}

static void on_child(int sig)
{
	(void)sig; /* only to interrupt the wait for the next request: reap() follows */
}

/* Serve requests until one says stop; 0, or 1 when the channel could not be opened. */
static int serve(const char *folder, const char *request_line, const char *reply_line)
{
	struct channel channel;
	char path[4200], text[256];
	struct sigaction child = { 0 };

	child.sa_handler = on_child;
	sigaction(SIGCHLD, &child, NULL);
	if (channel_open(&channel, folder, request_line, reply_line) < 0)
		return 1;
	snprintf(path, sizeof(path), "%s/ready", folder);
	snprintf(text, sizeof(text), "pid=%d\nbus=%s\ngpio_base=%s\nrelease=%s\n", getpid(),
		 bus_text, gpio_base_text, release);
	write_file(path, text, strlen(text), O_CREAT | O_TRUNC);
	channel_reply(&channel); /* ready */
	for (;;) {
		int stop;

		if (channel_wait(&channel) < 0) {
			reap();
			continue;
		}
		stop = serve_one(folder);
		channel_reply(&channel);
		if (stop)
			return 0;
	}
}

/* ---------------------------------------------------------------- init (UML) */

static void find_virtio_adapters(void)
{
	int64_t end = now_ns() + 2000000000LL;
	glob_t found;
	size_t i;

	while (!bus_text[0] && now_ns() < end) {
		if (!glob("/sys/bus/i2c/devices/i2c-*/name", 0, NULL, &found)) {
			for (i = 0; i < found.gl_pathc && !bus_text[0]; i++) {
				char *name = read_file(found.gl_pathv[i], 256, NULL);

				if (name && strstr(name, "virtio")) {
					const char *number = strstr(found.gl_pathv[i], "i2c-") + 4;

					snprintf(bus_text, sizeof(bus_text), "%d", atoi(number));
				}
				free(name);
			}
			globfree(&found);
		}
		if (!bus_text[0])
			sleep_ns(10000000);
	}
	if (!glob("/sys/class/gpio/gpiochip*/label", 0, NULL, &found)) {
		for (i = 0; i < found.gl_pathc && !gpio_base_text[0]; i++) {
			char *label = read_file(found.gl_pathv[i], 256, NULL), base[300], *value;

			if (label && !strncmp(label, "virtio", 6)) {
				snprintf(base, sizeof(base), "%s", found.gl_pathv[i]);
				strcpy(strrchr(base, '/'), "/base");
				value = read_file(base, 32, NULL);
				if (value) {
					snprintf(gpio_base_text, sizeof(gpio_base_text), "%d", atoi(value));
					free(value);
				}
			}
			free(label);
		}
		globfree(&found);
	}
}

static void power_off(void)
{
	sync();
	reboot(RB_POWER_OFF);
	for (;;)
		pause();
}

static int init(void)
{
	char *cmdline, *word, *save, script[4096] = "", out[4096] = "", vio[4096] = "",
	     modules[8192] = "", boot[64] = "", agent[4300] = "", mark[4400] = "",
	     request_line[16] = "", reply_line[16] = "";
	struct utsname names;
	pid_t child;
	int status = -1;

	mount("proc", "/proc", "proc", 0, NULL);
	mount("sys", "/sys", "sysfs", 0, NULL);
	mount("dev", "/dev", "devtmpfs", 0, NULL); /* EBUSY when DEVTMPFS_MOUNT did it */
	mount("run", "/run", "tmpfs", 0, "mode=0755");
	mkdir("/run/home", 0700);
	mkdir("/run/tmp", 01777);
	mount("shm", "/dev/shm", "tmpfs", 0, NULL);
	uname(&names);
	snprintf(release, sizeof(release), "%s", names.release);
	env_add("PATH", "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin");
	env_add("HOME", "/run/home");
	env_add("TMPDIR", "/run/tmp");
	env_add("GUEST_ENGINE", "uml");
	cmdline = read_file("/proc/cmdline", 1 << 16, NULL);
	for (word = cmdline ? strtok_r(cmdline, " \n", &save) : NULL; word;
	     word = strtok_r(NULL, " \n", &save)) {
		if (!strncmp(word, "guest_script=", 13))
			snprintf(script, sizeof(script), "%s", word + 13);
		else if (!strncmp(word, "guest_out=", 10))
			snprintf(out, sizeof(out), "%s", word + 10);
		else if (!strncmp(word, "guest_modroot=", 14))
			snprintf(modroot, sizeof(modroot), "%s", word + 14);
		else if (!strncmp(word, "guest_vio=", 10))
			snprintf(vio, sizeof(vio), "%s", word + 10);
		else if (!strncmp(word, "guest_modules=", 14))
			snprintf(modules, sizeof(modules), "%s", word + 14);
		else if (!strncmp(word, "guest_boot=", 11))
			snprintf(boot, sizeof(boot), "%s", word + 11);
		else if (!strncmp(word, "guest_agent=", 12))
			sscanf(word + 12, "%4095[^,],%15[^,],%15s", agent, request_line, reply_line);
		else if (isupper((unsigned char)word[0]) && strchr(word, '=')) {
			*strchr(word, '=') = 0;
			env_add(word, word + strlen(word) + 1);
		}
	}
	if (modroot[0]) {
		char folder[4200];

		snprintf(folder, sizeof(folder), "%s/lib/modules", modroot);
		if (!access("/lib/modules", F_OK))
			mount("modules", "/lib/modules", "hostfs", 0, folder);
	}
	if (out[0] && mount("results", out, "hostfs", 0, out) < 0)
		say("cannot mount the results folder %s: %s", out, strerror(errno));
	/* A reboot (sysrq b, a panic, reboot(2)) makes UML exec itself again with the same
	 * command line; the engine contract wants the guest to end instead. The first boot
	 * leaves a mark named by this boot's token, so the second one powers off at once. */
	if (boot[0] && out[0]) {
		snprintf(mark, sizeof(mark), "%s/.uml-boot-%s", out, boot);
		if (!access(mark, F_OK)) {
			say("the guest rebooted: powering off");
			unlink(mark);
			power_off();
		}
		write_file(mark, "", 0, O_CREAT);
	}
	if (vio[0]) {
		char path[4300];
		int error;

		snprintf(path, sizeof(path), "%s/i2c-virtio.ko", vio);
		error = load_module_file(path, "");
		if (error)
			say("insmod i2c-virtio failed: %s", strerror(error));
		find_virtio_adapters();
	}
	for (word = strtok_r(modules, ",", &save); word; word = strtok_r(NULL, ",", &save)) {
		int error = word[0] == '/' ? load_module_file(word, "") : modprobe(word, "");

		if (error)
			say("loading %s failed: %s", word, strerror(error));
	}
	env_add("BMG160_RESULTS", out);
	env_add("GUEST_OUT", out);
	env_add("GUEST_ROOT", modroot);
	{
		char folder[4300];

		snprintf(folder, sizeof(folder), "%s/lib/modules/%s", modroot, release);
		env_add("GUEST_MODULES", folder);
	}
	env_add("GUEST_I2C_BUS", bus_text);
	env_add("GUEST_GPIO_BASE", gpio_base_text);
	if (chdir("/") < 0)
		say("chdir /: %s", strerror(errno));
	if (agent[0]) {
		say("serving %s", agent);
		status = serve(agent, request_line, reply_line);
	} else if (script[0]) {
		fprintf(stderr, "init: running %s\n", script);
		child = fork();
		if (child == 0) {
			execle("/bin/sh", "sh", script, (char *)NULL, environment);
			_exit(127);
		}
		while (child > 0) {
			pid_t done = wait(&status);

			if (done == child || (done < 0 && errno != EINTR))
				break;
		}
		status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
		fprintf(stderr, "init: script exited with status %d\n", status);
	}
	if (out[0]) {
		char path[4200], text[16];

		snprintf(path, sizeof(path), "%s/exit-status", out);
		snprintf(text, sizeof(text), "%d\n", status);
		write_file(path, text, strlen(text), O_CREAT | O_TRUNC);
	}
	if (mark[0])
		unlink(mark);
	power_off();
	return 0;
}

/* ---------------------------------------------------------------- on the host */

static volatile sig_atomic_t guard_signal;

static void on_guard_signal(int sig)
{
	guard_signal = sig;
}

/* Run COMMAND in a process group of its own and wait for it; when our parent ends (the
 * harness died: PR_SET_PDEATHSIG) or SIGTERM comes, SIGTERM the whole group, SIGKILL it
 * GUARD_GRACE_S later; when COMMAND ends, SIGKILL what is left of its group (UML's helper
 * processes outlive its main process otherwise, holding the console pipe open). */
#define GUARD_GRACE_S 3
static int orphan_guard(int argc, char **argv)
{
	pid_t parent, child, done;
	struct sigaction action = { 0 };
	int status = 0, terminating = 0;

	if (argc < 5 || strcmp(argv[3], "--")) {
		say("usage: agent orphan-guard PPID -- COMMAND...");
		return 2;
	}
	parent = atoi(argv[2]);
	action.sa_handler = on_guard_signal;
	sigaction(SIGTERM, &action, NULL);
	sigaction(SIGINT, &action, NULL);
	sigaction(SIGHUP, &action, NULL);
	sigaction(SIGALRM, &action, NULL);
	if (prctl(PR_SET_PDEATHSIG, SIGTERM) < 0 || getppid() != parent)
		return 1; /* the parent is already gone */
	child = fork();
	if (child < 0) {
		say("fork: %s", strerror(errno));
		return 127;
	}
	if (child == 0) {
		struct sigaction plain = { 0 };

		plain.sa_handler = SIG_DFL;
		sigaction(SIGTERM, &plain, NULL);
		sigaction(SIGINT, &plain, NULL);
		sigaction(SIGHUP, &plain, NULL);
		sigaction(SIGALRM, &plain, NULL);
		setpgid(0, 0);
		execvp(argv[4], argv + 4);
		say("cannot run %s: %s", argv[4], strerror(errno));
		_exit(127);
	}
	setpgid(child, child); /* (also in the child: whichever runs first) */
	for (;;) {
		done = waitpid(child, &status, 0);
		if (done == child)
			break;
		if (done < 0 && errno != EINTR)
			break;
		if (guard_signal == SIGALRM) {
			kill(-child, SIGKILL);
		} else if (guard_signal && !terminating) {
			terminating = 1;
			kill(-child, SIGTERM);
			alarm(GUARD_GRACE_S);
		}
		guard_signal = 0;
	}
	kill(-child, SIGKILL);
	if (WIFEXITED(status))
		return WEXITSTATUS(status);
	return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

int main(int argc, char **argv)
{
	if (getpid() == 1)
		return init();
	if (argc >= 3 && !strcmp(argv[1], "orphan-guard"))
		return orphan_guard(argc, argv);
	if (argc == 5 && !strcmp(argv[1], "serve")) {
		struct utsname names;
		char **word;
		extern char **environ;
		const char *value;

		uname(&names);
		snprintf(release, sizeof(release), "%s", names.release);
		value = getenv("GUEST_ROOT");
		snprintf(modroot, sizeof(modroot), "%s", value ? value : "");
		value = getenv("GUEST_I2C_BUS");
		snprintf(bus_text, sizeof(bus_text), "%s", value ? value : "");
		value = getenv("GUEST_GPIO_BASE");
		snprintf(gpio_base_text, sizeof(gpio_base_text), "%s", value ? value : "");
		for (word = environ; *word && env_count < MAX_ENV; word++)
			environment[env_count++] = *word;
		environment[env_count] = NULL;
		return serve(argv[2], argv[3], argv[4]);
	}
	say("usage: agent serve FOLDER REQUEST_LINE REPLY_LINE | agent orphan-guard PPID -- CMD");
	return 2;
}

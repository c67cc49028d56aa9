/*
 * Self-test of the C client against the fake ecatd of clients/python/fake_ecatd.py
 * (started by clients/python/test_ecat_app.py, which compiles and runs this program).
 *
 *     test_client SOCKET
 *
 * The fake serves fake_ecatd.TEST_ENTRIES with initial_commit=4 and split answers. This
 * program asks its driver for each server-side step by printing a command line on stdout
 * (see FakeEcatd.command) and reading the reply line on stdin; its findings go to stderr.
 * Exit status 0: every check passed.
 */
#define _GNU_SOURCE

#include "ecat_app.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static int failures;

#define CHECK(cond)                                                                      \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);     \
            failures++;                                                                  \
        }                                                                                \
    } while (0)

#define CHECK_EQ(got, want)                                                              \
    do {                                                                                 \
        long long got_ = (long long)(got), want_ = (long long)(want);                    \
        if (got_ != want_) {                                                             \
            fprintf(stderr, "%s:%d: %s is %lld, not %lld (%s)\n", __FILE__, __LINE__,   \
                    #got, got_, want_, #want);                                           \
            failures++;                                                                  \
        }                                                                                \
    } while (0)

/* Asks the driver to do `cmd` server-side; its reply (after "ok") goes to `reply`. */
static void ask(const char *cmd, char *reply, size_t len)
{
    char line[512];
    printf("%s\n", cmd);
    fflush(stdout);
    if (fgets(line, sizeof line, stdin) == NULL) {
        fprintf(stderr, "the driver is gone (command %s)\n", cmd);
        exit(2);
    }
    line[strcspn(line, "\n")] = '\0';
    if (strncmp(line, "ok", 2) != 0) {
        fprintf(stderr, "command %s: %s\n", cmd, line);
        failures++;
    }
    if (reply != NULL)
        snprintf(reply, len, "%s", line);
}

static uint64_t monotonic_ns(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (uint64_t)now.tv_sec * 1000000000u + (uint64_t)now.tv_nsec;
}

static void tell(const char *cmd)
{
    ask(cmd, NULL, 0);
}

static ecat_app *attach(const char *path, int read_only)
{
    char err[256];
    ecat_app *app = ecat_app_connect(path, read_only, err, sizeof err);
    if (app == NULL) {
        fprintf(stderr, "connect: %s\n", err);
        exit(1);
    }
    return app;
}

static void check_commit(unsigned long long number, long long out1, long long setpoint)
{
    char reply[512];
    unsigned long long n = 0, stamp = 0;
    long long a = 99, b = 99;
    ask("commit", reply, sizeof reply);
    CHECK_EQ(sscanf(reply, "ok %llu %llu %lld %lld", &n, &stamp, &a, &b), 4);
    CHECK_EQ(n, number);
    CHECK_EQ(stamp, number);
    CHECK_EQ(a, out1);
    CHECK_EQ(b, setpoint);
}

int main(int argc, char **argv)
{
    const char *path;
    const ecat_app_entry *analog, *counter, *out1, *setpoint, *temperature;
    ecat_app *app, *other;
    char err[256], want[128];
    float celsius;
    uint32_t bits;
    uint64_t before;

    if (argc != 2) {
        fprintf(stderr, "usage: test_client SOCKET\n");
        return 2;
    }
    path = argv[1];

    /* Attach: the entry table. */
    app = attach(path, 0);
    CHECK_EQ(ecat_app_entry_count(app), 5);
    CHECK_EQ(ecat_app_generation(app), 1);
    CHECK_EQ(ecat_app_period_ns(app), 1000000);
    CHECK_EQ(ecat_app_cycle(app), 0);
    CHECK(ecat_app_entry_at(app, 5) == NULL);
    CHECK(ecat_app_find(app, 9, 0x6000, 1) == NULL);
    analog = ecat_app_find(app, 2, 0x6000, 1);
    counter = ecat_app_find(app, 2, 0x6010, 1);
    out1 = ecat_app_find(app, 1, 0x7000, 1);
    setpoint = ecat_app_find(app, 1, 0x7010, 2);
    temperature = ecat_app_find(app, 2, 0x6020, 0x11);
    if (!analog || !counter || !out1 || !setpoint || !temperature) {
        fprintf(stderr, "entries missing\n");
        return 1;
    }
    CHECK(analog == ecat_app_entry_at(app, 0));
    CHECK_EQ(analog->station, 0x1002);
    CHECK_EQ(analog->pdo, 0x1A00);
    CHECK_EQ(analog->direction, ECAT_APP_IN);
    CHECK_EQ(analog->data_type, ECAT_APP_INTEGER16);
    CHECK_EQ(analog->bit_offset, 3);
    CHECK_EQ(analog->bit_length, 16);
    CHECK(strcmp(analog->name, "Analog input") == 0);
    CHECK(strcmp(ecat_app_type_name(analog->data_type), "INTEGER16") == 0);
    CHECK(ecat_app_type_name(0) == NULL);
    CHECK_EQ(out1->direction, ECAT_APP_OUT);
    CHECK_EQ(out1->bit_offset, 69);
    CHECK_EQ(out1->bit_length, 1);

    /* No cycle yet: a timeout. Then one, with the time it was published. */
    CHECK_EQ(ecat_app_wait(app, 30), ECAT_APP_E_TIMEOUT);
    CHECK_EQ(ecat_app_published_ns(app), 0);
    before = monotonic_ns();
    tell("publish");
    CHECK_EQ(ecat_app_wait(app, 2000), 1);
    CHECK_EQ(ecat_app_cycle(app), 1);
    CHECK(ecat_app_published_ns(app) >= before);
    CHECK(ecat_app_published_ns(app) <= monotonic_ns());
    CHECK_EQ(ecat_app_read(app, analog), -2);
    CHECK_EQ(ecat_app_read(app, counter), 0xDEADBEEFLL);
    bits = (uint32_t)ecat_app_read(app, temperature);
    memcpy(&celsius, &bits, sizeof celsius);
    CHECK(celsius == 21.5f);
    CHECK_EQ(ecat_app_read(app, out1), 1);     /* as sent: not the owner */
    CHECK_EQ(ecat_app_read(app, setpoint), -5);
    CHECK_EQ(ecat_app_wait(app, 0), ECAT_APP_E_TIMEOUT); /* nothing newer */

    /* Writes are checked; commit needs ownership. */
    CHECK_EQ(ecat_app_write(app, analog, 1), ECAT_APP_E_NOT_OUTPUT);
    CHECK_EQ(ecat_app_write(app, out1, 2), ECAT_APP_E_RANGE);
    CHECK_EQ(ecat_app_write(app, setpoint, 128), ECAT_APP_E_RANGE);
    CHECK_EQ(ecat_app_write(app, setpoint, -129), ECAT_APP_E_RANGE);
    CHECK_EQ(ecat_app_write(NULL, setpoint, 1), ECAT_APP_E_INVALID);
    CHECK_EQ(ecat_app_commit(app), ECAT_APP_E_NOT_OWNER);
    CHECK(!ecat_app_owns(app));

    /* Claim: pending outputs start as sent; numbering continues from the region's 4. */
    CHECK_EQ(ecat_app_claim(app, err, sizeof err), 0);
    CHECK(ecat_app_owns(app));
    CHECK_EQ(ecat_app_read(app, out1), 1);
    CHECK_EQ(ecat_app_read(app, setpoint), -5);
    CHECK_EQ(ecat_app_write(app, out1, 0), 0);
    CHECK_EQ(ecat_app_write(app, setpoint, -128), 0);
    CHECK_EQ(ecat_app_read(app, out1), 0);
    CHECK_EQ(ecat_app_read(app, setpoint), -128);
    CHECK_EQ(ecat_app_commit(app), 0);
    check_commit(5, 0, -128);
    CHECK_EQ(ecat_app_write(app, setpoint, 127), 0);
    CHECK_EQ(ecat_app_commit(app), 0);
    check_commit(6, 0, 127);
    tell("publish"); /* the fake takes commit 6 into this frame */
    CHECK_EQ(ecat_app_wait(app, 2000), 2);
    CHECK_EQ(ecat_app_applied(app), 6);

    /* A second claim is refused with the owner's pid and uid; a monitor cannot claim. */
    other = attach(path, 0);
    CHECK_EQ(ecat_app_claim(other, err, sizeof err), ECAT_APP_E_REFUSED);
    snprintf(want, sizeof want, "owned pid=%ld uid=%ld", (long)getpid(), (long)getuid());
    if (strstr(err, want) == NULL) {
        fprintf(stderr, "refusal \"%s\" does not say \"%s\"\n", err, want);
        failures++;
    }
    ecat_app_close(other);
    other = attach(path, 1);
    CHECK_EQ(ecat_app_claim(other, err, sizeof err), ECAT_APP_E_REFUSED);
    CHECK(strstr(err, "read-only attachment") != NULL);
    ecat_app_close(other);

    /* The watchdog takes the outputs back, once; claiming again works. */
    tell("watchdog");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_WATCHDOG);
    CHECK(!ecat_app_owns(app));
    CHECK_EQ(ecat_app_commit(app), ECAT_APP_E_NOT_OWNER);
    CHECK_EQ(ecat_app_wait(app, 20), ECAT_APP_E_TIMEOUT);
    CHECK_EQ(ecat_app_claim(app, err, sizeof err), 0);
    CHECK_EQ(ecat_app_commit(app), 0);
    check_commit(5, 0, 127); /* a fresh region, starting from 4 again */
    CHECK_EQ(ecat_app_release(app), 0);
    CHECK(!ecat_app_owns(app));

    /* An event line that arrives in two pieces. */
    tell("partial");
    CHECK_EQ(ecat_app_wait(app, 50), ECAT_APP_E_TIMEOUT);
    tell("event dog");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_WATCHDOG);

    /* A new layout generation: every further call fails the same way. */
    CHECK_EQ(ecat_app_claim(app, err, sizeof err), 0);
    tell("event EVENT layout_changed 2");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_LAYOUT);
    CHECK(strstr(ecat_app_last_error(app), "generation 2") != NULL);
    CHECK(!ecat_app_owns(app));
    CHECK_EQ(ecat_app_wait(app, 0), ECAT_APP_E_LAYOUT);
    CHECK_EQ(ecat_app_claim(app, err, sizeof err), ECAT_APP_E_LAYOUT);
    CHECK_EQ(ecat_app_commit(app), ECAT_APP_E_LAYOUT);
    ecat_app_close(app);

    /* A line over 256 bytes is a protocol error. */
    app = attach(path, 0);
    CHECK_EQ(ecat_app_cycle(app), 2); /* connect copies the newest cycle */
    analog = ecat_app_find(app, 2, 0x6000, 1); /* entries live as long as their handle */
    CHECK_EQ(ecat_app_read(app, analog), -2);
    tell("longline");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_PROTOCOL);
    CHECK_EQ(ecat_app_wait(app, 0), ECAT_APP_E_PROTOCOL);
    ecat_app_close(app);

    /* ecatd shutting down, or closing the socket: closed, for good. */
    app = attach(path, 0);
    tell("event EVENT shutdown");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_CLOSED);
    CHECK_EQ(ecat_app_wait(app, 0), ECAT_APP_E_CLOSED);
    ecat_app_close(app);
    app = attach(path, 0);
    tell("disconnect");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_CLOSED);
    CHECK_EQ(ecat_app_wait(app, 0), ECAT_APP_E_CLOSED);
    CHECK_EQ(ecat_app_claim(app, err, sizeof err), ECAT_APP_E_CLOSED);
    ecat_app_close(app);

    /* The region marked stale: layout changed, to the next generation. */
    app = attach(path, 0);
    tell("stale");
    CHECK_EQ(ecat_app_wait(app, 2000), ECAT_APP_E_LAYOUT);
    CHECK(strstr(ecat_app_last_error(app), "generation 2") != NULL);
    ecat_app_close(app);

    CHECK(strcmp(ecat_app_strerror(ECAT_APP_E_TIMEOUT), "no cycle within the timeout") == 0);
    fprintf(stderr, "%s: %d failure(s)\n", argv[0], failures);
    return failures == 0 ? 0 : 1;
}

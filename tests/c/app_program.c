/*
 * A control program for the application-interface tests, on the C client (clients/c): the
 * twin of tests/src/bin/app_program.rs (same command line, same scenarios, same JSON lines
 * on stdout), so one test body in tests/tests/server/app.rs checks all three libraries.
 *
 *     cc -O2 -std=c11 -Wall -Wextra -Werror -pedantic -I clients/c \
 *        -o app_program tests/c/app_program.c clients/c/ecat_app.c
 *
 * `app_program SOCKET SCENARIO [ARG]`:
 * - `drive`: claims, takes the drive (slave 0) through controlword 6, 7, 15 until the
 *   statusword says "operation enabled", sets target position 123456 and waits until the
 *   actual position reads it back;
 * - `mirror`: claims, writes eight patterns to the DO8 (slave 1, 0x7000:01..08) and counts
 *   the cycles until the DI8 (slave 2, 0x6000:01..08) reads each back;
 * - `hold`: claims (or reports the refusal) and commits every cycle until killed;
 * - `monitor N`: read-only, reports the cycle numbers of N waits;
 * - `soak SECONDS`: claims and commits every cycle for that long, counting the cycles it
 *   missed and the commits the frames did not carry;
 * - `layout`: waits until the layout changes;
 * - `bench SECONDS`: the loop of the `app_cycle` benchmark (see the Rust program): every
 *   cycle reads the DI8, writes the DO8 (low nibble: the commit's tag, high nibble: the
 *   DI8's high nibble plus one) and commits; reports the wake-up latency, the commits the
 *   next frame carried, those a later one carried, those no frame carried, those whose
 *   next cycle the program missed, and the missed cycles.
 *
 * On an error it prints {"error": "<message>"} (worded as the Rust client's Display of that
 * error) and exits 1.
 */
#define _POSIX_C_SOURCE 200809L

#include "ecat_app.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Timeout of every wait, as WAIT in the Rust program; and of the waits in `layout`. */
#define WAIT_MS 2000
#define LAYOUT_WAIT_MS 30000

/* What ecat_app_claim puts before ecatd's reason for a refusal. */
#define REFUSED_PREFIX "refused by ecatd: "

/* The message of the error that ends the scenario (printed by main). */
static char failure[1024];

/* --- output --------------------------------------------------------------------------- */

/* Writes `s` as a JSON string (quoted, escaped). */
static void json_string(const char *s)
{
    putchar('"');
    for (; *s != '\0'; s++) {
        unsigned char c = (unsigned char)*s;
        switch (c) {
        case '"': fputs("\\\"", stdout); break;
        case '\\': fputs("\\\\", stdout); break;
        case '\n': fputs("\\n", stdout); break;
        case '\r': fputs("\\r", stdout); break;
        case '\t': fputs("\\t", stdout); break;
        default:
            if (c < 0x20 || c == 0x7F)
                printf("\\u%04x", c);
            else
                putchar(c);
        }
    }
    putchar('"');
}

/* Ends a result line and flushes it (the test reads lines while the program runs). */
static void end_line(void)
{
    putchar('\n');
    fflush(stdout);
}

/* --- errors --------------------------------------------------------------------------- */

#if defined(__GNUC__)
__attribute__((format(printf, 1, 2)))
#endif
static int fail(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(failure, sizeof failure, fmt, ap);
    va_end(ap);
    return -1;
}

/* Records a library error `code` of `app`, worded as the Rust client's Display of it. */
static int lib_fail(const ecat_app *app, int code)
{
    const char *detail = app != NULL ? ecat_app_last_error(app) : "";
    if (detail[0] == '\0' || code == ECAT_APP_E_INVALID)
        detail = ecat_app_strerror(code);
    switch (code) {
    case ECAT_APP_E_TIMEOUT:
        /* The detail names the milliseconds; Rust says "no cycle within the timeout". */
        return fail("%s", ecat_app_strerror(code));
    case ECAT_APP_E_PROTOCOL:
        return fail("protocol error: %s", detail);
    default:
        /* Layout: "layout changed (generation N): attach again"; watchdog, closed, not
         * owner: the Rust words; refused: "refused by ecatd: <reason>"; I/O: what the
         * kernel said. */
        return fail("%s", detail);
    }
}

/* Records a failed connect (ecat_app_connect gives no code, only the message). */
static int connect_fail(const char *err)
{
    return fail("%s", err);
}

/* The entry, or NULL with the Rust client's Error::NoSuchEntry recorded. */
static const ecat_app_entry *entry(const ecat_app *app, uint16_t slave, uint16_t index,
                                   uint8_t subindex)
{
    const ecat_app_entry *e = ecat_app_find(app, slave, index, subindex);
    if (e == NULL)
        fail("slave %u maps no entry 0x%04X:%02X", (unsigned)slave, (unsigned)index,
             (unsigned)subindex);
    return e;
}

/* Library calls: on a negative code, record it and leave the scenario with -1. */
#define TRY(app, call)                                 \
    do {                                               \
        int64_t rc_ = (call);                          \
        if (rc_ < 0) {                                 \
            lib_fail((app), (int)rc_);                 \
            goto out;                                  \
        }                                              \
    } while (0)

/* A wait: its cycle into `var`, or record the error and leave. */
#define WAIT_INTO(app, var, timeout)                   \
    do {                                               \
        int64_t rc_ = ecat_app_wait((app), (timeout)); \
        if (rc_ < 0) {                                 \
            lib_fail((app), (int)rc_);                 \
            goto out;                                  \
        }                                              \
        (var) = (uint64_t)rc_;                         \
    } while (0)

#define FIND(var, app, slave, index, subindex)                     \
    do {                                                           \
        if (((var) = entry((app), (slave), (index), (subindex))) == NULL) \
            goto out;                                              \
    } while (0)

static ecat_app *attach(const char *path, int read_only)
{
    char err[1024];
    ecat_app *app = ecat_app_connect(path, read_only, err, sizeof err);
    if (app == NULL)
        connect_fail(err);
    return app;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

/* --- scenarios: each returns 0, or -1 with `failure` set -------------------------------- */

static int drive(const char *path)
{
    static const struct { int64_t command; int64_t state; } steps[] = {
        {6, 0x21}, {7, 0x23}, {15, 0x27}};
    const ecat_app_entry *control, *status, *target, *actual;
    char err[1024];
    uint64_t start, cycle;
    size_t i;
    int result = -1;
    ecat_app *app = attach(path, 0);
    if (app == NULL)
        return -1;
    FIND(control, app, 0, 0x6040, 0);
    FIND(status, app, 0, 0x6041, 0);
    FIND(target, app, 0, 0x607A, 0);
    FIND(actual, app, 0, 0x6064, 0);
    TRY(app, ecat_app_claim(app, err, sizeof err));
    WAIT_INTO(app, start, WAIT_MS);
    for (i = 0; i < sizeof steps / sizeof steps[0]; i++) {
        uint64_t deadline;
        TRY(app, ecat_app_write(app, control, steps[i].command));
        TRY(app, ecat_app_commit(app));
        deadline = ecat_app_cycle(app) + 100;
        while ((ecat_app_read(app, status) & 0x6F) != steps[i].state) {
            WAIT_INTO(app, cycle, WAIT_MS);
            if (cycle > deadline) {
                /* Rust's {:#06x}: "0x" and at least four digits. */
                fail("protocol error: statusword 0x%04" PRIx64 " after controlword %" PRId64,
                     (uint64_t)ecat_app_read(app, status), steps[i].command);
                goto out;
            }
            TRY(app, ecat_app_commit(app));
        }
    }
    TRY(app, ecat_app_write(app, target, 123456));
    TRY(app, ecat_app_commit(app));
    while (ecat_app_read(app, actual) != 123456) {
        WAIT_INTO(app, cycle, WAIT_MS);
        TRY(app, ecat_app_commit(app));
    }
    printf("{\"statusword\": %" PRId64 ", \"actual\": %" PRId64 ", \"cycles\": %" PRIu64 "}",
           ecat_app_read(app, status), ecat_app_read(app, actual),
           ecat_app_cycle(app) - start);
    end_line();
    result = 0;
out:
    ecat_app_close(app);
    return result;
}

static int mirror(const char *path)
{
    static const uint8_t patterns[] = {0x01, 0x80, 0x55, 0xAA, 0xFF, 0x00, 0x0F, 0xF0};
    const ecat_app_entry *outputs[8], *inputs[8];
    char err[1024];
    uint64_t worst = 0, cycle;
    size_t p;
    int bit, result = -1;
    ecat_app *app = attach(path, 0);
    if (app == NULL)
        return -1;
    for (bit = 0; bit < 8; bit++)
        FIND(outputs[bit], app, 1, 0x7000, (uint8_t)(bit + 1));
    for (bit = 0; bit < 8; bit++)
        FIND(inputs[bit], app, 2, 0x6000, (uint8_t)(bit + 1));
    TRY(app, ecat_app_claim(app, err, sizeof err));
    WAIT_INTO(app, cycle, WAIT_MS);
    for (p = 0; p < sizeof patterns; p++) {
        uint8_t pattern = patterns[p];
        uint64_t committed;
        for (bit = 0; bit < 8; bit++)
            TRY(app, ecat_app_write(app, outputs[bit], (pattern >> bit) & 1));
        TRY(app, ecat_app_commit(app));
        committed = ecat_app_cycle(app);
        for (;;) {
            uint8_t seen = 0;
            WAIT_INTO(app, cycle, WAIT_MS);
            for (bit = 0; bit < 8; bit++)
                seen |= (uint8_t)(((uint8_t)ecat_app_read(app, inputs[bit]) & 1u) << bit);
            if (seen == pattern) {
                if (cycle - committed > worst)
                    worst = cycle - committed;
                break;
            }
            if (cycle - committed > 50) {
                /* Rust's {:#04x}: "0x" and at least two digits. */
                fail("protocol error: DI8 reads 0x%02x, DO8 was given 0x%02x",
                     (unsigned)seen, (unsigned)pattern);
                goto out;
            }
            TRY(app, ecat_app_commit(app));
        }
    }
    printf("{\"patterns\": 8, \"worst_cycles\": %" PRIu64 "}", worst);
    end_line();
    result = 0;
out:
    ecat_app_close(app);
    return result;
}

static int hold(const char *path)
{
    const ecat_app_entry *outputs[8];
    int channel;
    char err[1024];
    int rc, result = -1;
    ecat_app *app = attach(path, 0);
    if (app == NULL)
        return -1;
    for (channel = 0; channel < 8; channel++)
        FIND(outputs[channel], app, 1, 0x7000, (uint8_t)(channel + 1));
    rc = ecat_app_claim(app, err, sizeof err);
    if (rc == ECAT_APP_E_REFUSED) {
        /* ecatd's reason: what followed "ERR " (err is "refused by ecatd: <reason>"). */
        const char *reason = err;
        if (strncmp(reason, REFUSED_PREFIX, strlen(REFUSED_PREFIX)) == 0)
            reason += strlen(REFUSED_PREFIX);
        fputs("{\"claimed\": false, \"reason\": ", stdout);
        json_string(reason);
        putchar('}');
        end_line();
        result = 0;
        goto out;
    }
    TRY(app, rc);
    printf("{\"claimed\": true}");
    end_line();
    /* The DO8 at exactly 0x01, told apart from any safe value the tests configure. */
    for (channel = 0; channel < 8; channel++)
        TRY(app, ecat_app_write(app, outputs[channel], channel == 0 ? 1 : 0));
    for (;;) {
        TRY(app, ecat_app_wait(app, WAIT_MS));
        TRY(app, ecat_app_commit(app));
    }
out:
    ecat_app_close(app);
    return result;
}

static int monitor(const char *path, uint64_t waits)
{
    uint64_t first = 0, last = 0, count = 0, cycle;
    char err[1024];
    bool refused;
    int result = -1;
    ecat_app *app = attach(path, 1);
    if (app == NULL)
        return -1;
    refused = ecat_app_claim(app, err, sizeof err) == ECAT_APP_E_REFUSED;
    for (; count < waits; count++) {
        WAIT_INTO(app, cycle, WAIT_MS);
        if (count == 0)
            first = cycle;
        last = cycle;
    }
    printf("{\"claim_refused\": %s, \"first\": %" PRIu64 ", \"last\": %" PRIu64
           ", \"waits\": %" PRIu64 "}",
           refused ? "true" : "false", first, last, count);
    end_line();
    result = 0;
out:
    ecat_app_close(app);
    return result;
}

static int soak(const char *path, uint64_t seconds)
{
    const ecat_app_entry *output;
    char err[1024];
    uint64_t first, last, cycle, missed = 0, not_carried = 0, commits = 0;
    double end;
    int result = -1;
    ecat_app *app = attach(path, 0);
    if (app == NULL)
        return -1;
    FIND(output, app, 1, 0x7000, 1);
    TRY(app, ecat_app_claim(app, err, sizeof err));
    end = now_s() + (double)seconds;
    WAIT_INTO(app, first, WAIT_MS);
    last = first;
    while (now_s() < end) {
        WAIT_INTO(app, cycle, WAIT_MS);
        missed += cycle - last - 1;
        last = cycle;
        /* The commit of the last cycle went out in this one's frame, unless it was late. */
        if (commits > 0 && ecat_app_applied(app) != commits)
            not_carried++;
        TRY(app, ecat_app_write(app, output, (int64_t)(cycle & 1)));
        TRY(app, ecat_app_commit(app));
        commits++;
    }
    /* The last commit goes out with the next frame at the latest. */
    WAIT_INTO(app, cycle, WAIT_MS);
    WAIT_INTO(app, cycle, WAIT_MS);
    printf("{\"cycles\": %" PRIu64 ", \"missed\": %" PRIu64 ", \"not_carried\": %" PRIu64
           ", \"commits\": %" PRIu64 ", \"carried\": %" PRIu64 ", \"period_ns\": %" PRIu64 "}",
           last - first, missed, not_carried, commits, ecat_app_applied(app),
           ecat_app_period_ns(app));
    end_line();
    result = 0;
out:
    ecat_app_close(app);
    return result;
}

static int layout(const char *path)
{
    uint32_t generation;
    int result = -1;
    ecat_app *app = attach(path, 1);
    if (app == NULL)
        return -1;
    generation = ecat_app_generation(app);
    printf("{\"attached\": %" PRIu32 "}", generation);
    end_line();
    for (;;) {
        int64_t rc = ecat_app_wait(app, LAYOUT_WAIT_MS);
        unsigned long next;
        if (rc >= 0)
            continue;
        lib_fail(app, (int)rc);
        if (rc != ECAT_APP_E_LAYOUT)
            goto out;
        /* The library gives the new generation only in its message ("layout changed
         * (generation N): attach again"); ecat_app_generation stays the attached one. */
        if (sscanf(ecat_app_last_error(app), "layout changed (generation %lu)", &next) != 1) {
            fail("protocol error: no generation in \"%s\"", ecat_app_last_error(app));
            goto out;
        }
        printf("{\"layout_changed\": %lu, \"was\": %" PRIu32 "}", next, generation);
        end_line();
        result = 0;
        goto out;
    }
out:
    ecat_app_close(app);
    return result;
}

static uint64_t monotonic_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* The sample at quantile `q` of the sorted `samples` (0 when there are none). */
static uint64_t quantile(const uint64_t *samples, size_t n, double q)
{
    return n == 0 ? 0 : samples[(size_t)((double)(n - 1) * q)];
}

/* Commits not yet seen on the wire, oldest first: at most this many. */
#define PENDING 8

static int bench(const char *path, uint64_t seconds)
{
    const ecat_app_entry *outputs[8], *inputs[8];
    char err[1024];
    uint64_t period_ns, first, last, cycle, missed = 0, commits = 0, replaced = 0;
    uint64_t unstamped = 0, next_frame = 0, later = 0, after_miss = 0;
    uint64_t pending_commit[PENDING], pending_cycle[PENDING];
    uint64_t *wakes = NULL;
    size_t capacity, count = 0, pending = 0, i;
    double end;
    int bit, result = -1;
    ecat_app *app = attach(path, 0);
    if (app == NULL)
        return -1;
    for (bit = 0; bit < 8; bit++)
        FIND(outputs[bit], app, 1, 0x7000, (uint8_t)(bit + 1));
    for (bit = 0; bit < 8; bit++)
        FIND(inputs[bit], app, 2, 0x6000, (uint8_t)(bit + 1));
    TRY(app, ecat_app_claim(app, err, sizeof err));
    period_ns = ecat_app_period_ns(app);
    if (period_ns == 0)
        period_ns = 1;
    capacity = (size_t)(seconds * 1000000000u / period_ns) + 4096;
    wakes = malloc(capacity * sizeof *wakes);
    if (wakes == NULL) {
        fail("out of memory");
        goto out;
    }
    WAIT_INTO(app, first, WAIT_MS);
    last = first;
    end = now_s() + (double)seconds;
    while (now_s() < end) {
        uint64_t now, published;
        uint8_t seen = 0, value;
        WAIT_INTO(app, cycle, WAIT_MS);
        now = monotonic_ns();
        published = ecat_app_published_ns(app);
        if (published == 0)
            unstamped++;
        else if (count < capacity)
            wakes[count++] = now > published ? now - published : 0;
        missed += cycle - last - 1;
        for (bit = 0; bit < 8; bit++)
            seen |= (uint8_t)(((uint8_t)ecat_app_read(app, inputs[bit]) & 1u) << bit);
        /* The commit this cycle's frame carried: its tag is on the DI8's low nibble (as in
         * the Rust program). */
        for (i = 0; i < pending; i++) {
            if ((pending_commit[i] & 0xFu) == (uint64_t)(seen & 0xFu)) {
                size_t rest = pending - i - 1;
                replaced += i;
                if (last != pending_cycle[i])
                    later++;
                else if (cycle == pending_cycle[i] + 1)
                    next_frame++;
                else
                    after_miss++;
                memmove(pending_commit, pending_commit + i + 1, rest * sizeof *pending_commit);
                memmove(pending_cycle, pending_cycle + i + 1, rest * sizeof *pending_cycle);
                pending = rest;
                break;
            }
        }
        last = cycle;
        commits++;
        value = (uint8_t)((((seen >> 4) + 1u) & 0xFu) << 4 | (commits & 0xFu));
        for (bit = 0; bit < 8; bit++)
            TRY(app, ecat_app_write(app, outputs[bit], (value >> bit) & 1));
        TRY(app, ecat_app_commit(app));
        if (pending == PENDING) {
            /* Eight commits without one on the wire: the oldest will never be told apart. */
            memmove(pending_commit, pending_commit + 1, (PENDING - 1) * sizeof *pending_commit);
            memmove(pending_cycle, pending_cycle + 1, (PENDING - 1) * sizeof *pending_cycle);
            pending--;
            replaced++;
        }
        pending_commit[pending] = commits;
        pending_cycle[pending] = cycle;
        pending++;
    }
    qsort(wakes, count, sizeof *wakes, compare_u64);
    printf("{\"client\": \"c\", \"period_ns\": %" PRIu64 ", \"seconds\": %" PRIu64
           ", \"cycles\": %" PRIu64 ", \"waits\": %" PRIu64 ", \"missed\": %" PRIu64
           ", \"commits\": %" PRIu64 ", \"next_frame\": %" PRIu64 ", \"later\": %" PRIu64
           ", \"replaced\": %" PRIu64 ", \"after_miss\": %" PRIu64 ", \"unseen\": %zu"
           ", \"unstamped\": %" PRIu64
           ", \"wake_p50_ns\": %" PRIu64 ", \"wake_p99_ns\": %" PRIu64
           ", \"wake_max_ns\": %" PRIu64 "}",
           period_ns, seconds, last - first, (uint64_t)count + unstamped, missed, commits,
           next_frame, later, replaced, after_miss, pending,
           unstamped, quantile(wakes, count, 0.50), quantile(wakes, count, 0.99),
           count > 0 ? wakes[count - 1] : 0);
    end_line();
    result = 0;
out:
    free(wakes);
    ecat_app_close(app);
    return result;
}

/* --- main ----------------------------------------------------------------------------- */

/* As Rust's str::parse::<u64>().ok(): an optional '+' then ASCII digits, at most
 * 2^64 - 1; false otherwise. */
static bool parse_u64(const char *s, uint64_t *out)
{
    uint64_t value = 0;
    if (*s == '+')
        s++;
    if (*s == '\0')
        return false;
    for (; *s != '\0'; s++) {
        unsigned digit;
        if (*s < '0' || *s > '9')
            return false;
        digit = (unsigned)(*s - '0');
        if (value > (UINT64_MAX - digit) / 10u)
            return false;
        value = value * 10u + digit;
    }
    *out = value;
    return true;
}

int main(int argc, char **argv)
{
    const char *path, *scenario;
    uint64_t arg = 0;
    bool has_arg;
    int rc;
    if (argc < 3) {
        fprintf(stderr, "usage: app_program SOCKET SCENARIO [ARG]\n");
        return 2;
    }
    path = argv[1];
    scenario = argv[2];
    has_arg = argc > 3 && parse_u64(argv[3], &arg);
    if (strcmp(scenario, "drive") == 0) {
        rc = drive(path);
    } else if (strcmp(scenario, "mirror") == 0) {
        rc = mirror(path);
    } else if (strcmp(scenario, "hold") == 0) {
        rc = hold(path);
    } else if (strcmp(scenario, "monitor") == 0) {
        rc = monitor(path, has_arg ? arg : 100);
    } else if (strcmp(scenario, "soak") == 0) {
        rc = soak(path, has_arg ? arg : 60);
    } else if (strcmp(scenario, "layout") == 0) {
        rc = layout(path);
    } else if (strcmp(scenario, "bench") == 0) {
        rc = bench(path, has_arg ? arg : 10);
    } else {
        fprintf(stderr, "unknown scenario %s\n", scenario);
        return 2;
    }
    if (rc != 0) {
        fputs("{\"error\": ", stdout);
        json_string(failure);
        putchar('}');
        end_line();
        return 1;
    }
    return 0;
}

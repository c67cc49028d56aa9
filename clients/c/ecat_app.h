/*
 * ecat_app: a control program's side of ecatd's application interface, in C.
 *
 * Attach to ecatd over its Unix socket, follow the cycle through the shared process image,
 * own the outputs and commit them whole. The protocol and the shared memory layout are the
 * ones of docs/application.md; this library mirrors the Rust client (clients/rust/src/).
 *
 *     char err[256];
 *     ecat_app *app = ecat_app_connect(NULL, 0, err, sizeof err);
 *     const ecat_app_entry *in = ecat_app_find(app, 2, 0x6000, 1);
 *     const ecat_app_entry *out = ecat_app_find(app, 1, 0x7000, 1);
 *     ecat_app_claim(app, err, sizeof err);
 *     for (;;) {
 *         if (ecat_app_wait(app, 1000) < 0) break;
 *         ecat_app_write(app, out, ecat_app_read(app, in));
 *         ecat_app_commit(app);
 *     }
 *     ecat_app_close(app);
 *
 * C99 with POSIX and Linux calls (eventfd, SCM_RIGHTS, memfd mappings); no dependencies.
 * Everything is allocated by ecat_app_connect (and ecat_app_claim maps the commit region):
 * ecat_app_wait, ecat_app_read, ecat_app_write and ecat_app_commit never allocate.
 *
 * One handle is for one thread at a time: the library takes no locks.
 */
#ifndef ECAT_APP_H
#define ECAT_APP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The socket ecatd serves as a system service; used when neither the path argument nor
 * $ECAT_APP_SOCKET names one. */
#define ECAT_APP_SYSTEM_SOCKET "/run/ecatd/app.sock"

/* The protocol version this library speaks. */
#define ECAT_APP_PROTOCOL_VERSION 1

/* Bytes of an entry's name field in the shared entry table. */
#define ECAT_APP_NAME_LEN 46

/* ecat_app_entry.direction */
#define ECAT_APP_IN 0  /* slave to master */
#define ECAT_APP_OUT 1 /* master to slave */

/* CoE data type codes (ETG.1000.6 Table 64) as ecat_app_entry.data_type gives them; 0 when
 * ecatd does not know an entry's type. */
#define ECAT_APP_BOOLEAN 0x0001
#define ECAT_APP_INTEGER8 0x0002
#define ECAT_APP_INTEGER16 0x0003
#define ECAT_APP_INTEGER32 0x0004
#define ECAT_APP_UNSIGNED8 0x0005
#define ECAT_APP_UNSIGNED16 0x0006
#define ECAT_APP_UNSIGNED32 0x0007
#define ECAT_APP_REAL32 0x0008
#define ECAT_APP_INTEGER64 0x0015
#define ECAT_APP_UNSIGNED64 0x001B

/* Error codes: every function that can fail returns one of these (negative) values. */
enum {
    ECAT_APP_OK = 0,
    ECAT_APP_E_TIMEOUT = -1,    /* no cycle within the timeout */
    ECAT_APP_E_LAYOUT = -2,     /* the layout changed: close and attach again (sticky) */
    ECAT_APP_E_WATCHDOG = -3,   /* the watchdog (or ecatd) took the outputs back */
    ECAT_APP_E_CLOSED = -4,     /* ecatd closed the connection (sticky) */
    ECAT_APP_E_IO = -5,         /* a system call failed (errno tells which way) */
    ECAT_APP_E_PROTOCOL = -6,   /* ecatd sent something this library does not understand */
    ECAT_APP_E_REFUSED = -7,    /* ecatd refused the request (the reason is in err) */
    ECAT_APP_E_NOT_OUTPUT = -8, /* only output entries can be written */
    ECAT_APP_E_RANGE = -9,      /* the value does not fit the entry's type and bits */
    ECAT_APP_E_NOT_OWNER = -10, /* commit without owning the outputs: claim first */
    ECAT_APP_E_INVALID = -11    /* a NULL handle or entry */
};

/* An attachment to ecatd (opaque). */
typedef struct ecat_app ecat_app;

/* One mapped object of one slave, with its place in the image (the 64-byte record of
 * docs/application.md, "An entry"). Entries live as long as their handle. */
typedef struct ecat_app_entry {
    uint16_t slave;       /* ring position */
    uint16_t station;     /* station address */
    uint16_t pdo;         /* the PDO that maps it */
    uint16_t index;       /* object index */
    uint8_t subindex;     /* object subindex */
    uint8_t direction;    /* ECAT_APP_IN or ECAT_APP_OUT */
    uint16_t data_type;   /* CoE type code, 0: not known */
    uint32_t bit_offset;  /* first bit in the image (bit 0 = LSB of byte 0) */
    uint16_t bit_length;  /* bits it takes, 0..64 */
    char name[ECAT_APP_NAME_LEN + 1]; /* UTF-8, NUL-terminated */
} ecat_app_entry;

/*
 * Attaches to ecatd's socket at `path` (NULL: $ECAT_APP_SOCKET, else
 * ECAT_APP_SYSTEM_SOCKET). `read_only` non-zero attaches a monitor that can never claim.
 * Sends `HELLO 1 rw|ro`, maps the image region it receives read-only, checks its magic and
 * version, reads the entry table and copies the newest cycle (if any).
 *
 * Returns the handle, or NULL with a message in `err` (`errlen` bytes, may be 0).
 */
ecat_app *ecat_app_connect(const char *path, int read_only, char *err, size_t errlen);

/*
 * Takes the outputs. On success the pending outputs start as the last cycle's outputs as
 * sent, and commits continue the numbering of the commit region.
 *
 * Returns 0; ECAT_APP_E_REFUSED while another program owns them (err: "refused by ecatd:
 * owned pid=... uid=...") or for a read-only attachment; or another negative code.
 */
int ecat_app_claim(ecat_app *app, char *err, size_t errlen);

/*
 * Gives the outputs back (the safe outputs go out from the next cycle). Does nothing if
 * this program does not own them. Returns 0 or a negative code.
 */
int ecat_app_release(ecat_app *app);

/* Non-zero while this program owns the outputs. */
int ecat_app_owns(const ecat_app *app);

/*
 * Blocks until a cycle newer than the last one returned has completed (returns at once if
 * one already has), copies its inputs and outputs as sent, and returns its number (> 0).
 * `timeout_ms` < 0 waits without limit.
 *
 * Fails with ECAT_APP_E_TIMEOUT; ECAT_APP_E_LAYOUT when a new layout generation replaced
 * this one (every later call fails the same: close and attach again); ECAT_APP_E_WATCHDOG
 * once when ecatd took the outputs back (claim again to own them); ECAT_APP_E_CLOSED when
 * ecatd closed the connection or is shutting down (sticky); ECAT_APP_E_IO,
 * ECAT_APP_E_PROTOCOL (see ecat_app_last_error).
 */
int64_t ecat_app_wait(ecat_app *app, int timeout_ms);

/* The last cycle ecat_app_wait returned or ecat_app_connect copied (0: none yet). */
uint64_t ecat_app_cycle(const ecat_app *app);

/* When ecatd published the last cycle ecat_app_wait returned (or ecat_app_connect copied):
 * CLOCK_MONOTONIC in nanoseconds, the clock every process on this machine shares, so
 * clock_gettime(CLOCK_MONOTONIC) right after the wait minus this is the wake-up latency.
 * Copied with the cycle (one consistent slot). 0 before the first cycle, or from an ecatd
 * that does not write it. */
uint64_t ecat_app_published_ns(const ecat_app *app);

/* The layout generation this attachment reads. */
uint32_t ecat_app_generation(const ecat_app *app);

/* The cycle period ecatd runs, in nanoseconds. */
uint64_t ecat_app_period_ns(const ecat_app *app);

/* The commit number the last frame carried (0: none of this layout yet). */
uint64_t ecat_app_applied(const ecat_app *app);

/* How many entries the layout maps. */
size_t ecat_app_entry_count(const ecat_app *app);

/* Entry `i` (0 <= i < ecat_app_entry_count) in image order; NULL out of range. */
const ecat_app_entry *ecat_app_entry_at(const ecat_app *app, size_t i);

/* The entry index:subindex of the slave at ring position `slave`; NULL if none. Look
 * entries up once, before the loop. */
const ecat_app_entry *ecat_app_find(const ecat_app *app, uint16_t slave, uint16_t index,
                                    uint8_t subindex);

/*
 * The value of `entry` (one of this handle's) in the last cycle: an input as received; an
 * output as this program will commit it while it owns the outputs, else as the cycle sent
 * it. Sign-extended for the signed CoE types, zero-extended otherwise (an UNSIGNED64 above
 * INT64_MAX reads negative; cast it to uint64_t). REAL32 reads as its 32 raw bits: memcpy
 * them into a float. 0 for a NULL entry.
 */
int64_t ecat_app_read(const ecat_app *app, const ecat_app_entry *entry);

/*
 * Sets output `entry` to `value` for the next ecat_app_commit. Returns 0;
 * ECAT_APP_E_NOT_OUTPUT for an input; ECAT_APP_E_RANGE for a value the entry's type and
 * bits cannot hold (signed types: -2^(n-1)..2^(n-1)-1, others 0..2^n-1; 64-bit entries
 * take any value, as their raw bits).
 */
int ecat_app_write(ecat_app *app, const ecat_app_entry *entry, int64_t value);

/*
 * Hands ecatd every output written so far as one whole (docs/application.md,
 * "Committing"): the next cycle's frame carries all of them. Returns 0;
 * ECAT_APP_E_NOT_OWNER without ownership; ECAT_APP_E_LAYOUT/ECAT_APP_E_CLOSED once the
 * attachment ended.
 */
int ecat_app_commit(ecat_app *app);

/* A message for an ECAT_APP_E_* code (a static string). */
const char *ecat_app_strerror(int code);

/* What the last failing call on `app` said, in more detail than its code (never NULL). */
const char *ecat_app_last_error(const ecat_app *app);

/* The CoE name of a type code ("INTEGER16", ...); NULL for 0 or a code it does not know. */
const char *ecat_app_type_name(uint16_t data_type);

/* Detaches and frees the handle (an owner's outputs go to their safe values from the next
 * cycle). NULL is allowed. */
void ecat_app_close(ecat_app *app);

#ifdef __cplusplus
}
#endif

#endif /* ECAT_APP_H */

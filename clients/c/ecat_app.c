/*
 * ecat_app: a control program's side of ecatd's application interface (see ecat_app.h).
 *
 * The offsets, the line protocol and the seqlock are those of docs/application.md; the
 * behaviour mirrors the Rust client in clients/rust/src/ (client.rs, shm.rs, entry.rs,
 * protocol.rs, fd_passing.rs).
 *
 * Shared memory is only touched through __atomic builtins: 4- and 8-byte fields with
 * acquire loads and release stores, the data with relaxed accesses, plus the two fences of
 * the seqlock (a release fence after a slot's stamp is set to 0, an acquire fence after its
 * data is copied). The other process may write any byte at any time, so nothing here reads
 * a shared byte twice expecting the same value, and every offset taken from a header is
 * checked against the mapping before use.
 */
#define _GNU_SOURCE

#include "ecat_app.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the shared regions are little-endian; this library reads them with native loads"
#endif

#if defined(__GNUC__)
#define PRINTF_LIKE(f, a) __attribute__((format(printf, f, a)))
#else
#define PRINTF_LIKE(f, a)
#endif

/* docs/application.md, "The protocol". */
#define MAX_LINE 256          /* the longest line, newline included */
#define MAX_FDS 4             /* descriptors one message carries at most */
#define PENDING_CAP (4 * MAX_LINE)
#define ANSWER_TIMEOUT_S 5    /* how long a request's answer may take */

/* docs/application.md, "Shared memory, byte by byte". */
#define LAYOUT_VERSION 1u
#define SLOTS 3u
#define SLOT_HEADER 64u
#define SLOT_PUBLISHED_NS 16u /* u64 in an input slot: CLOCK_MONOTONIC ns of its publication */
#define ENTRY_SIZE 64u
#define ENTRIES_OFFSET 0x100u
#define PAGE 4096u
#define FLAG_STALE (1u << 1)

#define I_MAGIC 0x000u
#define I_VERSION 0x008u
#define I_FLAGS 0x00Cu
#define I_IMAGE_LEN 0x014u
#define I_ENTRY_COUNT 0x018u
#define I_ENTRY_SIZE 0x01Cu
#define I_ENTRIES 0x020u
#define I_SLOTS 0x024u
#define I_SLOT_STRIDE 0x028u
#define I_SLOT_COUNT 0x02Cu
#define I_PERIOD_NS 0x030u
#define I_CYCLE 0x038u
#define I_APPLIED 0x040u

#define C_MAGIC 0x000u
#define C_GENERATION 0x008u
#define C_IMAGE_LEN 0x00Cu
#define C_SLOTS 0x010u
#define C_SLOT_STRIDE 0x014u
#define C_SLOT_COUNT 0x018u
#define C_COMMIT 0x020u
#define C_FIRST_SLOT 0x040u

static const char IMAGE_MAGIC[8] = {'E', 'C', 'A', 'T', 'A', 'P', 'P', '\0'};
static const char COMMIT_MAGIC[8] = {'E', 'C', 'A', 'T', 'O', 'U', 'T', '\0'};

/* Why every further wait fails (the attachment's end is sticky). */
enum ended { ENDED_NONE, ENDED_LAYOUT, ENDED_CLOSED, ENDED_BROKEN };

/* One line from ecatd. */
enum line_kind {
    L_HELLO, L_CLAIMED, L_RELEASED, L_PONG, L_REFUSED, L_LAYOUT, L_WATCHDOG, L_SHUTDOWN
};

struct line {
    enum line_kind kind;
    uint32_t generation;    /* L_HELLO, L_LAYOUT */
    uint64_t length;        /* L_HELLO, L_CLAIMED: region bytes */
    char reason[MAX_LINE];  /* L_REFUSED */
};

struct ecat_app {
    int sock;
    int events;                 /* the eventfd, non-blocking */
    const uint8_t *image;       /* the image region, read-only */
    size_t image_map_len;
    uint8_t *commit;            /* the commit region while this program owns the outputs */
    size_t commit_map_len;
    size_t commit_stride;
    uint64_t last_commit;
    uint32_t generation;
    size_t image_len;
    size_t slots;               /* offset of the first input slot */
    size_t stride;              /* bytes per input slot */
    size_t entry_count;
    ecat_app_entry *entries;
    uint64_t cycle;             /* the cycle the buffers hold */
    uint64_t published_ns;      /* when ecatd published it (CLOCK_MONOTONIC, 0: not known) */
    uint8_t *inputs, *sent;     /* its inputs as received, outputs as sent */
    uint8_t *next_inputs, *next_sent; /* copies under way (swapped in when whole) */
    uint8_t *outputs;           /* what this program will commit */
    uint8_t *buffers;           /* the one allocation the five buffers above live in */
    char pending[PENDING_CAP];  /* bytes read that are not a whole line yet */
    size_t pending_len;
    enum ended ended;
    uint32_t ended_generation;
    char error[2 * MAX_LINE];
};

/* --- messages ------------------------------------------------------------------------ */

static void vformat(char *out, size_t len, const char *fmt, va_list ap)
{
    if (out != NULL && len > 0)
        vsnprintf(out, len, fmt, ap);
}

static void PRINTF_LIKE(3, 4) format(char *out, size_t len, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vformat(out, len, fmt, ap);
    va_end(ap);
}

/* Records what went wrong; returns `code` for the caller to pass on. */
static int PRINTF_LIKE(3, 4) fail(ecat_app *app, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vformat(app->error, sizeof app->error, fmt, ap);
    va_end(ap);
    return code;
}

static int fail_errno(ecat_app *app, const char *what)
{
    int saved = errno;
    fail(app, ECAT_APP_E_IO, "%s: %s", what, strerror(saved));
    errno = saved;
    return ECAT_APP_E_IO;
}

const char *ecat_app_strerror(int code)
{
    switch (code) {
    case ECAT_APP_OK: return "success";
    case ECAT_APP_E_TIMEOUT: return "no cycle within the timeout";
    case ECAT_APP_E_LAYOUT: return "layout changed: attach again";
    case ECAT_APP_E_WATCHDOG: return "the outputs were taken back (watchdog): claim again";
    case ECAT_APP_E_CLOSED: return "ecatd closed the connection";
    case ECAT_APP_E_IO: return "a system call failed";
    case ECAT_APP_E_PROTOCOL: return "protocol error";
    case ECAT_APP_E_REFUSED: return "refused by ecatd";
    case ECAT_APP_E_NOT_OUTPUT: return "the entry is an input";
    case ECAT_APP_E_RANGE: return "the value does not fit the entry";
    case ECAT_APP_E_NOT_OWNER: return "this program does not own the outputs: claim first";
    case ECAT_APP_E_INVALID: return "invalid argument";
    default: return "unknown error";
    }
}

const char *ecat_app_last_error(const ecat_app *app)
{
    return app != NULL ? app->error : "no attachment";
}

const char *ecat_app_type_name(uint16_t data_type)
{
    switch (data_type) {
    case 0x0001: return "BOOLEAN";
    case 0x0002: return "INTEGER8";
    case 0x0003: return "INTEGER16";
    case 0x0004: return "INTEGER32";
    case 0x0005: return "UNSIGNED8";
    case 0x0006: return "UNSIGNED16";
    case 0x0007: return "UNSIGNED32";
    case 0x0008: return "REAL32";
    case 0x0009: return "VISIBLE_STRING";
    case 0x000A: return "OCTET_STRING";
    case 0x000B: return "UNICODE_STRING";
    case 0x000C: return "TIME_OF_DAY";
    case 0x000D: return "TIME_DIFFERENCE";
    case 0x000F: return "DOMAIN";
    case 0x0010: return "INTEGER24";
    case 0x0011: return "REAL64";
    case 0x0012: return "INTEGER40";
    case 0x0013: return "INTEGER48";
    case 0x0014: return "INTEGER56";
    case 0x0015: return "INTEGER64";
    case 0x0016: return "UNSIGNED24";
    case 0x0018: return "UNSIGNED40";
    case 0x0019: return "UNSIGNED48";
    case 0x001A: return "UNSIGNED56";
    case 0x001B: return "UNSIGNED64";
    default: return NULL;
    }
}

/* --- shared memory (shm.rs) ---------------------------------------------------------- */

static size_t round64(size_t n)
{
    return (n + 63u) / 64u * 64u;
}

static size_t round_page(size_t n)
{
    return (n + PAGE - 1u) / PAGE * PAGE;
}

/* Whether `len` bytes at `offset` lie in a mapping of `map_len` bytes, `align`-aligned. */
static int in_map(size_t map_len, size_t offset, size_t len, size_t align)
{
    return offset <= map_len && map_len - offset >= len && offset % align == 0;
}

/* The u32 at `offset` (acquire); 0 outside the mapping. */
static uint32_t load_u32(const uint8_t *map, size_t map_len, size_t offset)
{
    if (map == NULL || !in_map(map_len, offset, 4, 4))
        return 0;
    return __atomic_load_n((const uint32_t *)(const void *)(map + offset), __ATOMIC_ACQUIRE);
}

/* The u64 at `offset` (acquire); 0 outside the mapping. */
static uint64_t load_u64(const uint8_t *map, size_t map_len, size_t offset)
{
    if (map == NULL || !in_map(map_len, offset, 8, 8))
        return 0;
    return __atomic_load_n((const uint64_t *)(const void *)(map + offset), __ATOMIC_ACQUIRE);
}

/* Stores `value` at the (checked, aligned) `offset` (release). */
static void store_u64(uint8_t *map, size_t offset, uint64_t value)
{
    __atomic_store_n((uint64_t *)(void *)(map + offset), value, __ATOMIC_RELEASE);
}

/* Copies `n` bytes out of shared memory with relaxed loads (8 at a time while `src` is
 * aligned, which slot data always is: slots start on 64-byte boundaries). */
static void copy_from_shared(uint8_t *dst, const uint8_t *src, size_t n)
{
    size_t i = 0;
    if (((uintptr_t)src & 7u) == 0) {
        for (; i + 8 <= n; i += 8) {
            uint64_t word = __atomic_load_n((const uint64_t *)(const void *)(src + i),
                                            __ATOMIC_RELAXED);
            memcpy(dst + i, &word, 8);
        }
    }
    for (; i < n; i++)
        dst[i] = __atomic_load_n(src + i, __ATOMIC_RELAXED);
}

/* Copies `n` bytes into shared memory with relaxed stores. */
static void copy_to_shared(uint8_t *dst, const uint8_t *src, size_t n)
{
    size_t i = 0;
    if (((uintptr_t)dst & 7u) == 0) {
        for (; i + 8 <= n; i += 8) {
            uint64_t word;
            memcpy(&word, src + i, 8);
            __atomic_store_n((uint64_t *)(void *)(dst + i), word, __ATOMIC_RELAXED);
        }
    }
    for (; i < n; i++)
        __atomic_store_n(dst + i, src[i], __ATOMIC_RELAXED);
}

/* Maps `len` bytes of `fd` shared (read-only or read-write); NULL with the error set. */
static void *map_region(ecat_app *app, int fd, uint64_t len, int writable, int *code)
{
    struct stat st;
    void *map;
    if (len == 0 || len % PAGE != 0 || len > SIZE_MAX) {
        *code = fail(app, ECAT_APP_E_PROTOCOL,
                     "region of %llu bytes: not a whole number of pages",
                     (unsigned long long)len);
        return NULL;
    }
    /* A mapping past the end of the file would fault (SIGBUS) on first touch. */
    if (fstat(fd, &st) != 0) {
        *code = fail_errno(app, "fstat of the region");
        return NULL;
    }
    if (st.st_size < 0 || (uint64_t)st.st_size < len) {
        *code = fail(app, ECAT_APP_E_PROTOCOL, "the region's file is shorter than %llu bytes",
                     (unsigned long long)len);
        return NULL;
    }
    map = mmap(NULL, (size_t)len, writable ? PROT_READ | PROT_WRITE : PROT_READ, MAP_SHARED,
               fd, 0);
    if (map == MAP_FAILED) {
        *code = fail_errno(app, "cannot map the region");
        return NULL;
    }
    return map;
}

/* --- entries (entry.rs) -------------------------------------------------------------- */

static int is_signed(const ecat_app_entry *e)
{
    switch (e->data_type) {
    case 0x0002: case 0x0003: case 0x0004: case 0x0010:
    case 0x0012: case 0x0013: case 0x0014: case 0x0015:
        return 1;
    default:
        return 0;
    }
}

static int fits(const ecat_app_entry *e, size_t image_len)
{
    return e->bit_length <= 64 &&
           (uint64_t)e->bit_offset + e->bit_length <= 8u * (uint64_t)image_len;
}

/* Its raw bits in `image` (little-endian, zero-extended); 0 if it does not fit. */
static uint64_t get_bits(const ecat_app_entry *e, const uint8_t *image, size_t image_len)
{
    uint64_t value = 0;
    unsigned i = 0;
    if (!fits(e, image_len))
        return 0;
    while (i < e->bit_length) { /* a byte (or the part of one the entry covers) at a time */
        uint32_t bit = e->bit_offset + i;
        unsigned shift = bit & 7u;
        unsigned take = 8u - shift;
        if (take > e->bit_length - i)
            take = e->bit_length - i;
        value |= (uint64_t)((image[bit >> 3] >> shift) & ((1u << take) - 1u)) << i;
        i += take;
    }
    return value;
}

/* Writes the low bit_length bits of `value` into `image`, no other bit; 0 if it does not
 * fit. */
static int set_bits(const ecat_app_entry *e, uint8_t *image, size_t image_len, uint64_t value)
{
    unsigned i = 0;
    if (!fits(e, image_len))
        return 0;
    while (i < e->bit_length) {
        uint32_t bit = e->bit_offset + i;
        unsigned shift = bit & 7u;
        unsigned take = 8u - shift;
        unsigned mask;
        if (take > e->bit_length - i)
            take = e->bit_length - i;
        mask = ((1u << take) - 1u) << shift;
        image[bit >> 3] = (uint8_t)((image[bit >> 3] & ~mask) |
                                    (((unsigned)(value >> i) << shift) & mask));
        i += take;
    }
    return 1;
}

/* Its value in `image`, sign-extended for the signed CoE types. */
static int64_t get_i64(const ecat_app_entry *e, const uint8_t *image, size_t image_len)
{
    uint64_t raw = get_bits(e, image, image_len);
    unsigned bits = e->bit_length;
    if (is_signed(e) && bits >= 1 && bits < 64 && (raw >> (bits - 1)) & 1u)
        raw |= UINT64_MAX << bits;
    return (int64_t)raw;
}

/* Whether `value` is representable in the entry's bits (as its type is signed or not). */
static int accepts(const ecat_app_entry *e, int64_t value)
{
    unsigned bits = e->bit_length;
    if (bits >= 64)
        return 1;
    if (bits == 0)
        return value == 0;
    if (is_signed(e)) {
        int64_t max = (int64_t)((UINT64_C(1) << (bits - 1)) - 1u);
        return value >= -max - 1 && value <= max;
    }
    return value >= 0 && (uint64_t)value < (UINT64_C(1) << bits);
}

/* The entry of a 64-byte record; 0 for a record that is not one (direction not 0 or 1). */
static int decode_entry(const uint8_t *r, ecat_app_entry *e)
{
    size_t n;
#define U16_AT(at) ((uint16_t)(r[at] | (unsigned)r[(at) + 1] << 8))
    if (r[9] > 1)
        return 0;
    e->slave = U16_AT(0);
    e->station = U16_AT(2);
    e->pdo = U16_AT(4);
    e->index = U16_AT(6);
    e->subindex = r[8];
    e->direction = r[9];
    e->data_type = U16_AT(10);
    e->bit_offset = (uint32_t)r[12] | (uint32_t)r[13] << 8 | (uint32_t)r[14] << 16 |
                    (uint32_t)r[15] << 24;
    e->bit_length = U16_AT(16);
#undef U16_AT
    for (n = 0; n < ECAT_APP_NAME_LEN && r[18 + n] != 0; n++)
        e->name[n] = (char)r[18 + n];
    e->name[n] = '\0';
    return 1;
}

/* --- lines (protocol.rs) ------------------------------------------------------------- */

/* A decimal number of at most `max`; 0 if `word` is not one. */
static int parse_number(const char *word, uint64_t max, uint64_t *out)
{
    uint64_t value = 0;
    if (*word == '\0')
        return 0;
    for (; *word != '\0'; word++) {
        unsigned digit = (unsigned)(*word - '0');
        if (*word < '0' || *word > '9' || value > (max - digit) / 10u)
            return 0;
        value = value * 10u + digit;
    }
    *out = value;
    return 1;
}

/* Parses one line (without its newline, NUL-terminated, at most MAX_LINE bytes). */
static int parse_line(ecat_app *app, char *text, struct line *out)
{
    char original[MAX_LINE];
    char *w[3] = {text, NULL, NULL};
    int n = 1;
    uint64_t a, b;
    char *space;
    snprintf(original, sizeof original, "%s", text);
    /* Split at the first two spaces, as splitn(3, ' '): the third word keeps the rest. */
    if ((space = strchr(text, ' ')) != NULL) {
        *space = '\0';
        w[1] = space + 1;
        n = 2;
        if ((space = strchr(w[1], ' ')) != NULL) {
            *space = '\0';
            w[2] = space + 1;
            n = 3;
        }
    }
    if (n == 3 && strcmp(w[0], "OK") == 0 && strcmp(w[1], "HELLO") == 0) {
        char *region = strchr(w[2], ' ');
        if (region == NULL)
            return fail(app, ECAT_APP_E_PROTOCOL, "\"%.128s\": two numbers expected", original);
        *region++ = '\0';
        if (!parse_number(w[2], UINT64_MAX, &a) || !parse_number(region, UINT64_MAX, &b))
            return fail(app, ECAT_APP_E_PROTOCOL, "\"%.128s\": not a number", original);
        if (a > UINT32_MAX)
            return fail(app, ECAT_APP_E_PROTOCOL, "%s: generation too large", w[2]);
        out->kind = L_HELLO;
        out->generation = (uint32_t)a;
        out->length = b;
    } else if (n == 3 && strcmp(w[0], "OK") == 0 && strcmp(w[1], "CLAIM") == 0) {
        if (!parse_number(w[2], UINT64_MAX, &b))
            return fail(app, ECAT_APP_E_PROTOCOL, "\"%.128s\": not a number", original);
        out->kind = L_CLAIMED;
        out->length = b;
    } else if (n == 2 && strcmp(w[0], "OK") == 0 && strcmp(w[1], "RELEASE") == 0) {
        out->kind = L_RELEASED;
    } else if (n == 2 && strcmp(w[0], "OK") == 0 && strcmp(w[1], "PING") == 0) {
        out->kind = L_PONG;
    } else if (strcmp(w[0], "ERR") == 0) {
        out->kind = L_REFUSED;
        snprintf(out->reason, sizeof out->reason, "%s", n > 1 ? original + 4 : "");
    } else if (n == 3 && strcmp(w[0], "EVENT") == 0 && strcmp(w[1], "layout_changed") == 0) {
        if (!parse_number(w[2], UINT64_MAX, &a))
            return fail(app, ECAT_APP_E_PROTOCOL, "\"%.128s\": not a number", original);
        if (a > UINT32_MAX)
            return fail(app, ECAT_APP_E_PROTOCOL, "%s: generation too large", w[2]);
        out->kind = L_LAYOUT;
        out->generation = (uint32_t)a;
    } else if (n == 2 && strcmp(w[0], "EVENT") == 0 && strcmp(w[1], "watchdog") == 0) {
        out->kind = L_WATCHDOG;
    } else if (n == 2 && strcmp(w[0], "EVENT") == 0 && strcmp(w[1], "shutdown") == 0) {
        out->kind = L_SHUTDOWN;
    } else {
        return fail(app, ECAT_APP_E_PROTOCOL, "unknown line \"%.128s\"", original);
    }
    return 0;
}

static int is_event(const struct line *line)
{
    return line->kind == L_LAYOUT || line->kind == L_WATCHDOG || line->kind == L_SHUTDOWN;
}

/* --- the attachment's state ---------------------------------------------------------- */

static void drop_commit(ecat_app *app)
{
    if (app->commit != NULL) {
        munmap(app->commit, app->commit_map_len);
        app->commit = NULL;
    }
}

/* Makes every further wait, claim and commit fail the same way. */
static void end(ecat_app *app, enum ended why, uint32_t generation)
{
    app->ended = why;
    app->ended_generation = generation;
    drop_commit(app);
}

static int check_ended(ecat_app *app)
{
    switch (app->ended) {
    case ENDED_LAYOUT:
        return fail(app, ECAT_APP_E_LAYOUT, "layout changed (generation %lu): attach again",
                    (unsigned long)app->ended_generation);
    case ENDED_CLOSED:
        return fail(app, ECAT_APP_E_CLOSED, "ecatd closed the connection");
    case ENDED_BROKEN:
        return fail(app, ECAT_APP_E_PROTOCOL, "a line from ecatd is longer than %d bytes",
                    MAX_LINE);
    case ENDED_NONE:
    default:
        return 0;
    }
}

/* An event line's consequence, as its error code. */
static int event(ecat_app *app, const struct line *line)
{
    switch (line->kind) {
    case L_LAYOUT:
        end(app, ENDED_LAYOUT, line->generation);
        return check_ended(app);
    case L_WATCHDOG:
        drop_commit(app);
        return fail(app, ECAT_APP_E_WATCHDOG,
                    "the outputs were taken back (watchdog): claim again");
    case L_SHUTDOWN:
        end(app, ENDED_CLOSED, 0);
        return check_ended(app);
    default:
        return fail(app, ECAT_APP_E_PROTOCOL, "unexpected line from ecatd");
    }
}

static int refusal(ecat_app *app, const struct line *line)
{
    if (line->kind == L_REFUSED)
        return fail(app, ECAT_APP_E_REFUSED, "refused by ecatd: %s", line->reason);
    return fail(app, ECAT_APP_E_PROTOCOL, "unexpected answer from ecatd");
}

/* --- the socket (fd_passing.rs, client.rs) ------------------------------------------- */

static int send_line(ecat_app *app, const char *text)
{
    char line[MAX_LINE];
    int len = snprintf(line, sizeof line, "%s\n", text);
    size_t done = 0;
    if (len < 0 || (size_t)len >= sizeof line)
        return fail(app, ECAT_APP_E_INVALID, "request too long");
    while (done < (size_t)len) {
        /* MSG_NOSIGNAL: a closed peer is an error, not SIGPIPE. */
        ssize_t sent = send(app->sock, line + done, (size_t)len - done, MSG_NOSIGNAL);
        if (sent < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EPIPE || errno == ECONNRESET) {
                end(app, ENDED_CLOSED, 0);
                return check_ended(app);
            }
            return fail_errno(app, "cannot send to ecatd");
        }
        done += (size_t)sent;
    }
    return 0;
}

/* Reads more bytes into the line buffer with the descriptors that come with them (closed
 * on exec; beyond `cap` they are closed). Returns the bytes read, 0 when ecatd closed the
 * connection, or a negative code. */
static int fill(ecat_app *app, int *fds, size_t *nfds, size_t cap)
{
    union {
        struct cmsghdr align;
        char buf[CMSG_SPACE(MAX_FDS * sizeof(int))];
    } control;
    struct iovec iov;
    struct msghdr msg;
    struct cmsghdr *cmsg;
    size_t room = PENDING_CAP - app->pending_len;
    ssize_t got;
    if (room == 0)
        return fail(app, ECAT_APP_E_PROTOCOL, "a line from ecatd is too long");
    iov.iov_base = app->pending + app->pending_len;
    iov.iov_len = room < MAX_LINE ? room : MAX_LINE;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.buf;
    msg.msg_controllen = sizeof control.buf;
    do
        got = recvmsg(app->sock, &msg, MSG_CMSG_CLOEXEC);
    while (got < 0 && errno == EINTR);
    if (got < 0) {
        if (errno == ECONNRESET)
            return 0;
        if (errno == EAGAIN || errno == EWOULDBLOCK)
            return fail(app, ECAT_APP_E_IO, "no answer from ecatd within %d s",
                        ANSWER_TIMEOUT_S);
        return fail_errno(app, "cannot read from ecatd");
    }
    for (cmsg = CMSG_FIRSTHDR(&msg); cmsg != NULL; cmsg = CMSG_NXTHDR(&msg, cmsg)) {
        size_t i, count;
        if (cmsg->cmsg_level != SOL_SOCKET || cmsg->cmsg_type != SCM_RIGHTS)
            continue;
        count = (cmsg->cmsg_len - CMSG_LEN(0)) / sizeof(int);
        for (i = 0; i < count; i++) {
            int fd;
            memcpy(&fd, CMSG_DATA(cmsg) + i * sizeof(int), sizeof fd);
            if (*nfds < cap)
                fds[(*nfds)++] = fd;
            else
                close(fd);
        }
    }
    if (msg.msg_flags & MSG_CTRUNC)
        return fail(app, ECAT_APP_E_PROTOCOL, "more descriptors than expected");
    app->pending_len += (size_t)got;
    return (int)got;
}

static void close_fds(int *fds, size_t *nfds)
{
    size_t i;
    for (i = 0; i < *nfds; i++)
        close(fds[i]);
    *nfds = 0;
}

/* Takes the first whole line out of the buffer: 1 (in `out`), 0 if there is none yet, or
 * a negative code. A line over MAX_LINE bytes ends the attachment. */
static int take_line(ecat_app *app, struct line *out)
{
    char text[MAX_LINE];
    const char *nl = memchr(app->pending, '\n', app->pending_len);
    size_t len;
    int rc;
    if ((nl == NULL && app->pending_len >= MAX_LINE) ||
        (nl != NULL && (size_t)(nl - app->pending) + 1 > MAX_LINE)) {
        end(app, ENDED_BROKEN, 0);
        return check_ended(app);
    }
    if (nl == NULL)
        return 0;
    len = (size_t)(nl - app->pending);
    memcpy(text, app->pending, len);
    text[len] = '\0';
    app->pending_len -= len + 1;
    memmove(app->pending, nl + 1, app->pending_len);
    if (memchr(text, '\0', len) != NULL)
        return fail(app, ECAT_APP_E_PROTOCOL, "a line from ecatd holds a NUL byte");
    rc = parse_line(app, text, out);
    return rc < 0 ? rc : 1;
}

/* The answer to the request just sent; events before it are taken as they come. */
static int answer(ecat_app *app, struct line *out, int *fds, size_t *nfds, size_t cap)
{
    for (;;) {
        int rc = take_line(app, out);
        if (rc < 0)
            return rc;
        if (rc == 0) {
            rc = fill(app, fds, nfds, cap);
            if (rc < 0)
                return rc;
            if (rc == 0) {
                end(app, ENDED_CLOSED, 0);
                return check_ended(app);
            }
            continue;
        }
        if (!is_event(out))
            return 0;
        (void)event(app, out); /* a watchdog before the answer still ends the ownership */
        rc = check_ended(app);
        if (rc < 0)
            return rc;
    }
}

/* Handles the whole event lines in the buffer; `more` is what the read before gave (0: the
 * connection ended). The first event that ends something is returned. */
static int take_events(ecat_app *app, int more)
{
    char first_error[sizeof app->error];
    int first = 0;
    struct line line;
    for (;;) {
        int rc = take_line(app, &line);
        if (rc < 0)
            return rc;
        if (rc == 0)
            break;
        rc = event(app, &line);
        if (rc < 0 && first == 0) {
            first = rc;
            memcpy(first_error, app->error, sizeof first_error);
        }
    }
    if (more == 0) {
        end(app, ENDED_CLOSED, 0);
        if (first == 0)
            return check_ended(app);
    }
    if (first != 0)
        memcpy(app->error, first_error, sizeof first_error);
    return first;
}

/* Reads the event lines waiting on the socket. */
static int read_events(ecat_app *app)
{
    int fds[MAX_FDS] = {-1, -1, -1, -1};
    size_t nfds = 0;
    int more = fill(app, fds, &nfds, MAX_FDS);
    close_fds(fds, &nfds); /* descriptors only come with answers */
    if (more < 0)
        return more;
    return take_events(app, more);
}

/* --- the cycle ----------------------------------------------------------------------- */

/* Copies the newest published cycle (docs/application.md, "Reading a cycle"): 1 if it was
 * whole, 0 if there is none or ecatd reused its slot while we copied. The buffers read()
 * uses only change when a copy is whole. */
static int copy_newest(ecat_app *app)
{
    uint64_t cycle = load_u64(app->image, app->image_map_len, I_CYCLE);
    size_t slot;
    uint8_t *swap;
    uint64_t published;
    if (cycle == 0)
        return 0;
    slot = app->slots + (size_t)(cycle % SLOTS) * app->stride;
    if (load_u64(app->image, app->image_map_len, slot) != cycle)
        return 0;
    published = load_u64(app->image, app->image_map_len, slot + SLOT_PUBLISHED_NS);
    copy_from_shared(app->next_inputs, app->image + slot + SLOT_HEADER, app->image_len);
    copy_from_shared(app->next_sent, app->image + slot + SLOT_HEADER + round64(app->image_len),
                     app->image_len);
    __atomic_thread_fence(__ATOMIC_ACQUIRE);
    if (load_u64(app->image, app->image_map_len, slot) != cycle)
        return 0;
    swap = app->inputs;
    app->inputs = app->next_inputs;
    app->next_inputs = swap;
    swap = app->sent;
    app->sent = app->next_sent;
    app->next_sent = swap;
    app->cycle = cycle;
    app->published_ns = published;
    return 1;
}

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

int64_t ecat_app_wait(ecat_app *app, int timeout_ms)
{
    int64_t deadline;
    if (app == NULL)
        return ECAT_APP_E_INVALID;
    deadline = timeout_ms < 0 ? -1 : now_ns() + (int64_t)timeout_ms * 1000000;
    for (;;) {
        struct pollfd polls[2];
        int left = -1;
        int rc = check_ended(app);
        if (rc < 0)
            return rc;
        if (load_u32(app->image, app->image_map_len, I_FLAGS) & FLAG_STALE) {
            /* The region does not say which generation replaced it: the next one. */
            end(app, ENDED_LAYOUT, app->generation + 1u);
            return check_ended(app);
        }
        if (load_u64(app->image, app->image_map_len, I_CYCLE) > app->cycle && copy_newest(app))
            return (int64_t)app->cycle;
        if (memchr(app->pending, '\n', app->pending_len) != NULL) {
            /* Event lines that came in with an earlier answer: the socket will not become
             * readable for them again. */
            rc = take_events(app, -1);
            if (rc < 0)
                return rc;
            continue;
        }
        if (deadline >= 0) {
            int64_t remaining = deadline - now_ns();
            if (remaining <= 0)
                return fail(app, ECAT_APP_E_TIMEOUT, "no cycle within %d ms", timeout_ms);
            /* In whole milliseconds, rounded up: never a busy poll with 0. */
            remaining = (remaining + 999999) / 1000000;
            left = remaining > INT_MAX ? INT_MAX : (int)remaining;
        }
        polls[0].fd = app->events;
        polls[0].events = POLLIN;
        polls[0].revents = 0;
        polls[1].fd = app->sock;
        polls[1].events = POLLIN;
        polls[1].revents = 0;
        if (poll(polls, 2, left) < 0) {
            if (errno == EINTR)
                continue;
            return fail_errno(app, "poll");
        }
        if (polls[0].revents != 0) {
            uint64_t count;
            /* Non-blocking: EAGAIN means another thread drained it first. */
            if (read(app->events, &count, sizeof count) < 0 && errno != EAGAIN)
                return fail_errno(app, "reading the eventfd");
        }
        if (polls[1].revents != 0) {
            rc = read_events(app);
            if (rc < 0)
                return rc;
        }
    }
}

uint64_t ecat_app_cycle(const ecat_app *app)
{
    return app != NULL ? app->cycle : 0;
}

uint64_t ecat_app_published_ns(const ecat_app *app)
{
    return app != NULL ? app->published_ns : 0;
}

uint32_t ecat_app_generation(const ecat_app *app)
{
    return app != NULL ? app->generation : 0;
}

uint64_t ecat_app_period_ns(const ecat_app *app)
{
    return app != NULL ? load_u64(app->image, app->image_map_len, I_PERIOD_NS) : 0;
}

uint64_t ecat_app_applied(const ecat_app *app)
{
    return app != NULL ? load_u64(app->image, app->image_map_len, I_APPLIED) : 0;
}

/* --- entries ------------------------------------------------------------------------- */

size_t ecat_app_entry_count(const ecat_app *app)
{
    return app != NULL ? app->entry_count : 0;
}

const ecat_app_entry *ecat_app_entry_at(const ecat_app *app, size_t i)
{
    return app != NULL && i < app->entry_count ? &app->entries[i] : NULL;
}

const ecat_app_entry *ecat_app_find(const ecat_app *app, uint16_t slave, uint16_t index,
                                    uint8_t subindex)
{
    size_t i;
    if (app == NULL)
        return NULL;
    for (i = 0; i < app->entry_count; i++) {
        const ecat_app_entry *e = &app->entries[i];
        if (e->slave == slave && e->index == index && e->subindex == subindex)
            return e;
    }
    return NULL;
}

int64_t ecat_app_read(const ecat_app *app, const ecat_app_entry *entry)
{
    const uint8_t *image;
    if (app == NULL || entry == NULL)
        return 0;
    if (entry->direction == ECAT_APP_IN)
        image = app->inputs;
    else
        image = app->commit != NULL ? app->outputs : app->sent;
    return get_i64(entry, image, app->image_len);
}

int ecat_app_write(ecat_app *app, const ecat_app_entry *entry, int64_t value)
{
    if (app == NULL || entry == NULL)
        return ECAT_APP_E_INVALID;
    if (entry->direction != ECAT_APP_OUT)
        return fail(app, ECAT_APP_E_NOT_OUTPUT, "entry 0x%04X:%02X of slave %u is an input",
                    (unsigned)entry->index, (unsigned)entry->subindex, (unsigned)entry->slave);
    if (!accepts(entry, value) || !set_bits(entry, app->outputs, app->image_len, (uint64_t)value))
        return fail(app, ECAT_APP_E_RANGE, "%lld does not fit the entry 0x%04X:%02X (%u bits)",
                    (long long)value, (unsigned)entry->index, (unsigned)entry->subindex,
                    (unsigned)entry->bit_length);
    return 0;
}

/* --- ownership ----------------------------------------------------------------------- */

int ecat_app_owns(const ecat_app *app)
{
    return app != NULL && app->commit != NULL;
}

int ecat_app_claim(ecat_app *app, char *err, size_t errlen)
{
    struct line line;
    int fds[MAX_FDS] = {-1, -1, -1, -1};
    size_t nfds = 0;
    uint8_t *region = NULL;
    size_t stride, len = 0;
    int rc;
    if (app == NULL) {
        format(err, errlen, "no attachment");
        return ECAT_APP_E_INVALID;
    }
    rc = check_ended(app);
    if (rc == 0)
        rc = send_line(app, "CLAIM");
    if (rc == 0)
        rc = answer(app, &line, fds, &nfds, MAX_FDS);
    if (rc == 0 && line.kind != L_CLAIMED)
        rc = refusal(app, &line);
    if (rc == 0 && nfds != 1)
        rc = fail(app, ECAT_APP_E_PROTOCOL, "CLAIM without its descriptor");
    if (rc == 0) {
        region = map_region(app, fds[0], line.length, 1, &rc);
        len = (size_t)line.length;
    }
    close_fds(fds, &nfds);
    if (rc < 0) {
        format(err, errlen, "%s", app->error);
        return rc;
    }
    stride = SLOT_HEADER + round64(app->image_len);
    if (memcmp(region + C_MAGIC, COMMIT_MAGIC, 8) != 0 ||
        load_u32(region, len, C_GENERATION) != app->generation ||
        load_u32(region, len, C_IMAGE_LEN) != app->image_len ||
        load_u32(region, len, C_SLOTS) != C_FIRST_SLOT ||
        load_u32(region, len, C_SLOT_STRIDE) != stride ||
        load_u32(region, len, C_SLOT_COUNT) != SLOTS ||
        round_page(C_FIRST_SLOT + SLOTS * stride) > len) {
        munmap(region, len);
        rc = fail(app, ECAT_APP_E_PROTOCOL, "the commit region does not match the layout");
        format(err, errlen, "%s", app->error);
        return rc;
    }
    drop_commit(app);
    /* Outputs this program does not write keep what the cycle sends now. */
    memcpy(app->outputs, app->sent, app->image_len);
    app->commit = region;
    app->commit_map_len = len;
    app->commit_stride = stride;
    /* Continue the numbering: ecatd takes only a commit newer than the last it saw. */
    app->last_commit = load_u64(region, len, C_COMMIT);
    return 0;
}

int ecat_app_release(ecat_app *app)
{
    struct line line;
    int fds[MAX_FDS] = {-1, -1, -1, -1};
    size_t nfds = 0;
    int rc;
    if (app == NULL)
        return ECAT_APP_E_INVALID;
    if (app->commit == NULL)
        return 0;
    drop_commit(app);
    rc = send_line(app, "RELEASE");
    if (rc == 0)
        rc = answer(app, &line, fds, &nfds, MAX_FDS);
    close_fds(fds, &nfds);
    if (rc == 0 && line.kind != L_RELEASED)
        rc = refusal(app, &line);
    return rc;
}

int ecat_app_commit(ecat_app *app)
{
    uint64_t number;
    size_t slot;
    int rc;
    if (app == NULL)
        return ECAT_APP_E_INVALID;
    rc = check_ended(app);
    if (rc < 0)
        return rc;
    if (app->commit == NULL)
        return fail(app, ECAT_APP_E_NOT_OWNER, "%s", ecat_app_strerror(ECAT_APP_E_NOT_OWNER));
    number = app->last_commit + 1;
    slot = C_FIRST_SLOT + (size_t)(number % SLOTS) * app->commit_stride;
    /* docs/application.md, "Committing": stamp 0, release fence, data, stamp, commit. */
    store_u64(app->commit, slot, 0);
    __atomic_thread_fence(__ATOMIC_RELEASE);
    copy_to_shared(app->commit + slot + SLOT_HEADER, app->outputs, app->image_len);
    store_u64(app->commit, slot, number);
    store_u64(app->commit, C_COMMIT, number);
    app->last_commit = number;
    return 0;
}

/* --- attach and detach --------------------------------------------------------------- */

/* Reads and checks the image region's header and entry table; allocates the buffers. */
static int load_layout(ecat_app *app)
{
    const uint8_t *m = app->image;
    size_t len = app->image_map_len;
    size_t count, table, i, buffer;
    uint8_t *buffers;
    if (memcmp(m + I_MAGIC, IMAGE_MAGIC, 8) != 0 || load_u32(m, len, I_VERSION) != LAYOUT_VERSION)
        return fail(app, ECAT_APP_E_PROTOCOL, "not an image region of layout version 1");
    app->image_len = load_u32(m, len, I_IMAGE_LEN);
    count = load_u32(m, len, I_ENTRY_COUNT);
    table = load_u32(m, len, I_ENTRIES);
    if (load_u32(m, len, I_ENTRY_SIZE) != ENTRY_SIZE)
        return fail(app, ECAT_APP_E_PROTOCOL, "entry size is not 64");
    if (!in_map(len, table, count * ENTRY_SIZE, 1))
        return fail(app, ECAT_APP_E_PROTOCOL, "entry table beyond the region");
    app->entries = calloc(count > 0 ? count : 1, sizeof *app->entries);
    if (app->entries == NULL)
        return fail(app, ECAT_APP_E_IO, "out of memory");
    for (i = 0; i < count; i++) {
        uint8_t record[ENTRY_SIZE];
        copy_from_shared(record, m + table + i * ENTRY_SIZE, ENTRY_SIZE);
        if (!decode_entry(record, &app->entries[i]) || !fits(&app->entries[i], app->image_len))
            return fail(app, ECAT_APP_E_PROTOCOL, "entry %zu is malformed", i);
    }
    app->entry_count = count;
    app->slots = load_u32(m, len, I_SLOTS);
    app->stride = load_u32(m, len, I_SLOT_STRIDE);
    if (app->slots != round64(ENTRIES_OFFSET + count * ENTRY_SIZE) ||
        app->stride != SLOT_HEADER + 2 * round64(app->image_len) ||
        load_u32(m, len, I_SLOT_COUNT) != SLOTS ||
        round_page(app->slots + SLOTS * app->stride) > len)
        return fail(app, ECAT_APP_E_PROTOCOL, "slots do not match the image size");
    /* Inputs, outputs as sent, the two copies under way, and the pending outputs. */
    buffer = app->image_len > 0 ? app->image_len : 1;
    buffers = calloc(5, buffer);
    if (buffers == NULL)
        return fail(app, ECAT_APP_E_IO, "out of memory");
    app->buffers = buffers;
    app->inputs = buffers;
    app->sent = buffers + buffer;
    app->next_inputs = buffers + 2 * buffer;
    app->next_sent = buffers + 3 * buffer;
    app->outputs = buffers + 4 * buffer;
    return 0;
}

ecat_app *ecat_app_connect(const char *path, int read_only, char *err, size_t errlen)
{
    struct sockaddr_un addr;
    struct timeval timeout;
    struct line line;
    int fds[MAX_FDS] = {-1, -1, -1, -1};
    size_t nfds = 0;
    int rc, flags;
    void *map;
    ecat_app *app = calloc(1, sizeof *app);
    if (app == NULL) {
        format(err, errlen, "out of memory");
        return NULL;
    }
    app->sock = -1;
    app->events = -1;
    if (path == NULL)
        path = getenv("ECAT_APP_SOCKET");
    if (path == NULL)
        path = ECAT_APP_SYSTEM_SOCKET;

    memset(&addr, 0, sizeof addr);
    addr.sun_family = AF_UNIX;
    if (strlen(path) >= sizeof addr.sun_path) {
        rc = fail(app, ECAT_APP_E_INVALID, "socket path too long: %s", path);
        goto failed;
    }
    memcpy(addr.sun_path, path, strlen(path) + 1);
    app->sock = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (app->sock < 0) {
        rc = fail_errno(app, "socket");
        goto failed;
    }
    if (connect(app->sock, (const struct sockaddr *)&addr, sizeof addr) != 0) {
        rc = fail(app, ECAT_APP_E_IO, "cannot attach to %s: %s", path, strerror(errno));
        goto failed;
    }
    /* An answer not back in this long means ecatd is stuck; wait polls on its own. */
    timeout.tv_sec = ANSWER_TIMEOUT_S;
    timeout.tv_usec = 0;
    if (setsockopt(app->sock, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout) != 0) {
        rc = fail_errno(app, "setsockopt");
        goto failed;
    }
    rc = send_line(app, read_only ? "HELLO 1 ro" : "HELLO 1 rw");
    if (rc == 0)
        rc = answer(app, &line, fds, &nfds, MAX_FDS);
    if (rc == 0 && line.kind != L_HELLO)
        rc = refusal(app, &line);
    if (rc == 0 && nfds != 2)
        rc = fail(app, ECAT_APP_E_PROTOCOL, "HELLO without its two descriptors");
    if (rc < 0)
        goto failed;
    app->generation = line.generation;
    map = map_region(app, fds[0], line.length, 0, &rc);
    if (map == NULL)
        goto failed;
    app->image = map;
    app->image_map_len = (size_t)line.length;
    close(fds[0]); /* the mapping stays */
    app->events = fds[1];
    nfds = 0;
    /* Reading the eventfd must never block (another thread may drain it first). The flag
     * is the open file's, shared with ecatd, whose writes it does not change. */
    flags = fcntl(app->events, F_GETFL);
    if (flags < 0 || fcntl(app->events, F_SETFL, flags | O_NONBLOCK) != 0) {
        rc = fail_errno(app, "fcntl on the eventfd");
        goto failed;
    }
    rc = load_layout(app);
    if (rc < 0)
        goto failed;
    /* Start from the newest cycle, so the first read sees real values. */
    (void)copy_newest(app);
    app->error[0] = '\0';
    return app;

failed:
    close_fds(fds, &nfds);
    format(err, errlen, "%s", app->error);
    ecat_app_close(app);
    return NULL;
}

void ecat_app_close(ecat_app *app)
{
    if (app == NULL)
        return;
    drop_commit(app);
    if (app->image != NULL)
        munmap((void *)(uintptr_t)app->image, app->image_map_len);
    if (app->events >= 0)
        close(app->events);
    if (app->sock >= 0)
        close(app->sock);
    free(app->entries);
    free(app->buffers);
    free(app);
}

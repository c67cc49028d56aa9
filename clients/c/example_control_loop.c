/*
 * A control loop on ecatd's cycle: owns the outputs and, every cycle, mirrors the EL1008's
 * eight inputs (slave 2, 0x6000:1..8) to the EL2008's eight outputs (slave 1, 0x7000:1..8).
 * Prints the cycle count every second.
 *
 *     cc -O2 -std=c11 -Wall -Wextra -Werror -o example example_control_loop.c ecat_app.c
 *     ./example [socket|-] [cycles]
 *
 * socket: ecatd's application socket ("-" or absent: $ECAT_APP_SOCKET, else
 * /run/ecatd/app.sock); cycles: stop after this many (absent or 0: run until SIGINT/SIGTERM).
 */
#define _GNU_SOURCE

#include "ecat_app.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define CHANNELS 8

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static double seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 && strcmp(argv[1], "-") != 0 ? argv[1] : NULL;
    long cycles = argc > 2 ? strtol(argv[2], NULL, 10) : 0;
    const ecat_app_entry *inputs[CHANNELS], *outputs[CHANNELS];
    char err[256];
    long done = 0;
    double last_print;
    int status = 0, i;
    struct sigaction sa;
    ecat_app *app;

    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    app = ecat_app_connect(path, 0, err, sizeof err);
    if (app == NULL) {
        fprintf(stderr, "example: %s\n", err);
        return 1;
    }
    printf("attached: generation %lu, %zu entries, period %.3f ms\n",
           (unsigned long)ecat_app_generation(app), ecat_app_entry_count(app),
           (double)ecat_app_period_ns(app) / 1e6);

    /* Look the entries up once: the loop itself only reads, writes and commits. */
    for (i = 0; i < CHANNELS; i++) {
        inputs[i] = ecat_app_find(app, 2, 0x6000, (uint8_t)(i + 1));
        outputs[i] = ecat_app_find(app, 1, 0x7000, (uint8_t)(i + 1));
        if (inputs[i] == NULL || outputs[i] == NULL) {
            fprintf(stderr, "example: the layout maps no 2:0x6000:%d or 1:0x7000:%d\n",
                    i + 1, i + 1);
            ecat_app_close(app);
            return 1;
        }
    }

    if (ecat_app_claim(app, err, sizeof err) != 0) {
        fprintf(stderr, "example: cannot claim the outputs: %s\n", err);
        ecat_app_close(app);
        return 1;
    }

    last_print = seconds();
    while (!stop && (cycles <= 0 || done < cycles)) {
        int64_t cycle = ecat_app_wait(app, 1000);
        if (cycle == ECAT_APP_E_TIMEOUT) {
            fprintf(stderr, "example: no cycle within 1 s\n");
            continue;
        }
        if (cycle == ECAT_APP_E_WATCHDOG) {
            /* The outputs were taken back (we were too slow): own them again. */
            fprintf(stderr, "example: %s\n", ecat_app_last_error(app));
            if (ecat_app_claim(app, err, sizeof err) != 0) {
                fprintf(stderr, "example: cannot claim the outputs again: %s\n", err);
                status = 1;
                break;
            }
            continue;
        }
        if (cycle < 0) {
            /* Layout changed or ecatd gone: a real program would attach again. */
            fprintf(stderr, "example: %s\n", ecat_app_last_error(app));
            status = 1;
            break;
        }
        for (i = 0; i < CHANNELS; i++)
            ecat_app_write(app, outputs[i], ecat_app_read(app, inputs[i]));
        if (ecat_app_commit(app) != 0) {
            fprintf(stderr, "example: commit: %s\n", ecat_app_last_error(app));
            status = 1;
            break;
        }
        done++;
        if (seconds() - last_print >= 1.0) {
            last_print = seconds();
            printf("cycle %lld, %ld cycles mirrored\n", (long long)cycle, done);
            fflush(stdout);
        }
    }
    printf("cycle %llu, %ld cycles mirrored\n", (unsigned long long)ecat_app_cycle(app), done);
    ecat_app_release(app);
    ecat_app_close(app);
    return status;
}

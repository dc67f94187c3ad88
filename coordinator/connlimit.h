/* connlimit.h - caps on the coordinator's connections (issue 20), after
 * Redis `maxclients` and nginx `limit_conn`: a total, and per peer
 * address two classes:
 *   open   - a connection before its hello, and a client after it: what
 *            anyone who can reach the port can hold; capped low;
 *   worker - a worker that finished its hello (with a token: proved it): a
 *            host may run many (a container farm behind one address), so
 *            its cap is separate and higher.
 * A refusal names the address, the cap and its option; refusals are
 * logged at most once per CONNLIMIT_LOG_S per cap (counting the others),
 * never once per attempt. A cap of 0 is no cap (`tessera render`'s own
 * farm). Loop thread only. */
#ifndef TESSERA_CONNLIMIT_H
#define TESSERA_CONNLIMIT_H

#include <stddef.h>

#define CONNLIMIT_LOG_S 10.0

typedef enum { CONNLIMIT_OPEN, CONNLIMIT_WORKER } connlimit_class;

typedef struct {
    int max_total;      /* every connection (--max-connections) */
    int max_open;       /* per address, before hello and clients (--max-per-address) */
    int max_workers;    /* per address, workers after hello (--max-workers-per-address) */
} connlimit_caps;

typedef struct connlimit connlimit;

/* A table for these caps. NULL when out of memory. */
connlimit *connlimit_new(const connlimit_caps *caps);
void connlimit_free(connlimit *l);

/* Count a new connection from ip (no port) in the open class. Returns 0, or
 * -1 with the refusal in why ("127.0.0.3 has 8 connections open before or
 * without a worker hello (--max-per-address 8)"). */
int connlimit_admit(connlimit *l, const char *ip, char *why, size_t why_len);

/* One open connection of ip becomes a worker. Returns 0, or -1 with the
 * refusal in why (it stays counted as open until released). */
int connlimit_promote(connlimit *l, const char *ip, char *why, size_t why_len);

/* A connection of ip in class cls went away. Can't fail. */
void connlimit_release(connlimit *l, const char *ip, connlimit_class cls);

/* Connections counted now. */
int connlimit_total(const connlimit *l);

/* Whether to log a refusal of kind (0: total, 1: open, 2: worker) at time
 * now (seconds): 1 at most once per CONNLIMIT_LOG_S, with *unlogged the
 * refusals of that kind since the last line; 0 counts this one. */
int connlimit_should_log(connlimit *l, int kind, double now, unsigned long *unlogged);

/* The kind (for connlimit_should_log) of the refusal connlimit_admit or
 * connlimit_promote just made. */
int connlimit_last_kind(const connlimit *l);

/* Defaults from the descriptor limit: raise RLIMIT_NOFILE's soft limit
 * toward its hard limit (as Redis does), keep `reserve` descriptors for
 * files, and cap the total at 10,000; the open class at an eighth of the
 * total (16 to 1,024: a load test's 1,000 simulated workers handshake at
 * once from one address), workers at half of it. Fills caps (fields
 * already non-zero are kept) and returns the soft descriptor limit. */
long connlimit_defaults(connlimit_caps *caps, int reserve);

/* The ip of "ADDRESS:PORT" (conn_peer_address) into out. Can't fail. */
void connlimit_ip_of(const char *addr_port, char *out, size_t len);

#endif

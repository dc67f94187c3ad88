/* client.h - the command-line client of a running coordinator. */
#ifndef TESSERA_CLIENT_H
#define TESSERA_CLIENT_H

/* Run `tessera submit|status|workers|cancel|fetch ...`; argv[0] is the
 * subcommand. Returns the exit status (0, 1 failure, 2 usage). */
int client_main(int argc, char **argv);

#endif

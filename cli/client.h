/* client.h - the command-line client of a running coordinator.
 *
 * Folder cli/: the command line; stands on coordinator/ and common/, and
 * nothing stands on it (README "Where things are"). */
#ifndef TESSERA_CLIENT_H
#define TESSERA_CLIENT_H

/* Run `tessera submit|status|workers|cancel|fetch ...`; argv[0] is the
 * subcommand. Returns the exit status (0, 1 failure, 2 usage). */
int client_main(int argc, char **argv);

#endif

/**
 * @file msid_devdesc_file.h
 * @brief Read an msid-device/1 description (TOML, docs/devices.md) into an
 *        ::msid_devdesc. Host side: the host's tick loop and msid-devsim read
 *        descriptions with it; a device's firmware has its map compiled in.
 *
 * Every problem is one message naming the file, the line and the key: a TOML
 * syntax error, a missing or unknown key (a misspelt `max_step` must not pass
 * silently), a value of the wrong type or out of range, a register written
 * as a 1-based Modicon number. ::msid_devdesc_check runs on the result.
 */
#ifndef MSID_DEVDESC_FILE_H
#define MSID_DEVDESC_FILE_H

#include "msid_devdesc.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * @brief Read and check the description in file `path`.
 * @param err  the message, cap bytes (256 or more)
 * @return 0, or -1 with err set (d is then unspecified)
 */
int msid_devdesc_load(const char *path, msid_devdesc *d, char *err, size_t cap);

/**
 * @brief Read and check a description from text (len bytes); `source` names it in messages and relative DBC
 *        paths resolve against its folder.
 * @return 0, or -1 with err set
 */
int msid_devdesc_parse(const char *text, size_t len, const char *source, msid_devdesc *d, char *err, size_t cap);

#ifdef __cplusplus
}
#endif
#endif

/* Files of schemas/ embedded at build time (server/embed.cmake). */
#ifndef NTSD_ASSETS_H
#define NTSD_ASSETS_H

#include <stddef.h>

typedef struct ntsd_asset {
    const char* name;         /* "scene", "result", "error", "openapi" */
    const char* content_type;
    const char* data;         /* NUL-terminated */
    size_t size;              /* bytes, without the NUL */
} ntsd_asset;

extern const ntsd_asset ntsd_assets[];
extern const int ntsd_asset_count;

#endif

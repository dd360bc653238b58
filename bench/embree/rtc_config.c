/* Replaces the configuration string of Embree's rtcNewDevice with $EMBER_EMBREE_CONFIG, for
   bench/embree/run.sh's EMBREE_ISA (embreex calls rtcNewDevice(NULL) and cannot pass one).
   Loaded with LD_PRELOAD, it comes first in symbol lookup; the real function is looked up in
   the libembree4 that embreex's extension module loaded (a dlopen'ed, so local, library that
   RTLD_NEXT does not search). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <link.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int find_embree(struct dl_phdr_info *info, size_t size, void *out) {
    (void)size;
    if (info->dlpi_name && strstr(info->dlpi_name, "libembree4")) {
        *(const char **)out = info->dlpi_name;
        return 1;
    }
    return 0;
}

void *rtcNewDevice(const char *config) {
    static void *(*real)(const char *);
    if (!real) {
        const char *path = NULL;
        dl_iterate_phdr(find_embree, &path);
        void *lib = path ? dlopen(path, RTLD_LAZY | RTLD_NOLOAD) : NULL;
        if (lib) real = (void *(*)(const char *))dlsym(lib, "rtcNewDevice");
        if (!real) {
            fprintf(stderr, "rtc_config shim: libembree4's rtcNewDevice not found\n");
            abort();
        }
    }
    const char *override = getenv("EMBER_EMBREE_CONFIG");
    return real(override && *override ? override : config);
}

/* Out-of-memory sweep of ntsj_handle, as libuv's test-loop-oom.c: fail the Nth
 * allocation (through nts_set_allocator) for N = 1, 2, ... until a request
 * succeeds, and check that every path answers (an error document or
 * NTS_ENOMEM), never crashes, and frees every byte it took. Run by
 * tests/python/test_cli.py on each bundled example and a few broken requests.
 *
 *   ntscontact_codec_oom FILE...   exit 0 when all hold */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/codec.h>

static long alloc_calls, fail_at, live;

static void* hook_alloc(size_t size, void* user) {
    void* p;
    (void)user;
    if (++alloc_calls == fail_at) return NULL;
    p = malloc(size);
    if (p) ++live;
    return p;
}

static void hook_free(void* ptr, void* user) {
    (void)user;
    if (ptr) --live;
    free(ptr);
}

static char* slurp(const char* path, size_t* n) {
    FILE* f = fopen(path, "rb");
    char* buf;
    long len;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    len = ftell(f);
    fseek(f, 0, SEEK_SET);
    buf = (char*)malloc((size_t)len + 1);
    if (buf && fread(buf, 1, (size_t)len, f) != (size_t)len) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    *n = (size_t)len;
    return buf;
}

static int sweep(const char* name, const char* json, size_t n, ntsj_mode mode) {
    ntsj_config cfg = ntsj_default_config();
    long k;
    cfg.mode = mode;
    for (k = 1; k < 100000; ++k) {
        ntsj_response r;
        int rc;
        alloc_calls = 0;
        live = 0;
        fail_at = k;
        rc = ntsj_handle(json, n, &cfg, &r);
        if (rc == 0 && !r.body) {
            printf("FAIL %s: fail at %ld: rc 0 without a body\n", name, k);
            return 1;
        }
        if (rc != 0 && (r.body || r.http_status != 500)) {
            printf("FAIL %s: fail at %ld: rc %d with body %p status %d\n", name, k, rc, (void*)r.body, r.http_status);
            return 1;
        }
        ntsj_response_free(&r);
        if (live != 0) {
            printf("FAIL %s: fail at %ld: %ld blocks leaked\n", name, k, live);
            return 1;
        }
        if (alloc_calls < fail_at) { /* no allocation failed: the sweep is complete */
            printf("%s: %ld allocations, every failure point answered and freed everything\n", name, k - 1);
            return 0;
        }
    }
    printf("FAIL %s: sweep did not finish\n", name);
    return 1;
}

int main(int argc, char** argv) {
    int i, failures = 0;
    static const char* const broken[] = {
        "{\"version\":1,\"options\":{\"penalty\":1},\"bodies\":[{\"id\":\"a\",\"nodes\":[[0,0],[1,0],[1,1]]},"
        "{\"id\":\"a\",\"nodes\":[[3,0],[4,0],[4,1]]}]}",
        "{\"version\":1,\"options\":{\"penalty\":1},\"bodies\":[{\"id\":\"a\",\"nodes\":[[0,0],[1,0],[1,0],[0,1]]}]}",
        "{\"version\":1,\"options\":{\"penalty\":1},\"bodies\":[{\"id\":1,\"nodes\":[[0,0],[1,0],[1,1],[0,1]],"
        "\"triangles\":[[0,1,2],[0,2,3],[0,1,3]]}]}",
        "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]",
    };
    nts_set_allocator(hook_alloc, hook_free, NULL);
    for (i = 1; i < argc; ++i) {
        size_t n = 0;
        char* json = slurp(argv[i], &n);
        if (!json) {
            printf("FAIL cannot read %s\n", argv[i]);
            return 1;
        }
        failures += sweep(argv[i], json, n, NTSJ_EVALUATE);
        failures += sweep(argv[i], json, n, NTSJ_VALIDATE);
        free(json);
    }
    for (i = 0; i < (int)(sizeof broken / sizeof broken[0]); ++i)
        failures += sweep("broken request", broken[i], strlen(broken[i]), NTSJ_EVALUATE);
    nts_set_allocator(NULL, NULL, NULL);
    return failures ? 1 : 0;
}

/* Allocation failure in the codec (issue 7, libuv's test-loop-oom.c): for each
 * scene file given, in both modes (evaluate with every output, validate), fail
 * allocation N = 1, 2, ... of ntsj_handle until a run goes through untouched.
 * The failing allocator sits behind both hooks the codec's work goes through:
 * nts_set_allocator (core, codec buffers, decoded arrays) and cJSON_InitHooks
 * (the parse tree). For every N:
 *   - ntsj_handle never crashes and returns 0 or NTS_ENOMEM;
 *   - the response is either exactly the reference response (elapsed_ms aside:
 *     the refused block was not needed, or retried) or an out_of_memory error
 *     document with HTTP 500 (rc 0), or no body at all (rc NTS_ENOMEM);
 *   - every block is freed once the response is freed (live count 0).
 * Usage: test_codec_alloc FILE|DIR... (directories: every *.json inside). */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cjson/cJSON.h>

#include <ntscontact/codec.h>

typedef struct failing_alloc {
    long calls, fail_at, failed, live;
} failing_alloc;

static failing_alloc g_fa;

static void* fa_malloc(size_t size) {
    void* p;
    ++g_fa.calls;
    if (g_fa.fail_at > 0 && g_fa.calls == g_fa.fail_at) {
        ++g_fa.failed;
        return NULL;
    }
    p = malloc(size);
    if (p != NULL) ++g_fa.live;
    return p;
}

static void fa_free_plain(void* ptr) {
    if (ptr == NULL) return;
    --g_fa.live;
    free(ptr);
}

static void* fa_alloc(size_t size, void* user) {
    (void)user;
    return fa_malloc(size);
}

static void fa_free(void* ptr, void* user) {
    (void)user;
    fa_free_plain(ptr);
}

static void hooks_on(long fail_at) {
    cJSON_Hooks h;
    memset(&g_fa, 0, sizeof g_fa);
    g_fa.fail_at = fail_at;
    h.malloc_fn = fa_malloc;
    h.free_fn = fa_free_plain;
    cJSON_InitHooks(&h);
    nts_set_allocator(fa_alloc, fa_free, NULL);
}

static void hooks_off(void) {
    cJSON_InitHooks(NULL);
    nts_set_allocator(NULL, NULL, NULL);
}

/* The body with the value of "elapsed_ms" blanked, the one field that differs
 * between two runs of the same request. Returns a malloc'ed copy. */
static char* without_elapsed(const char* body) {
    char* s = (char*)malloc(strlen(body) + 1);
    const char* p = body;
    char* o = s;
    const char* key = "\"elapsed_ms\"";
    if (s == NULL) return NULL;
    while (*p) {
        if (strncmp(p, key, strlen(key)) == 0) {
            memcpy(o, key, strlen(key));
            o += strlen(key);
            p += strlen(key);
            while (*p == ':' || *p == ' ') *o++ = *p++;
            *o++ = '#';
            while (*p && *p != ',' && *p != '}' && *p != '\n') ++p;
        } else {
            *o++ = *p++;
        }
    }
    *o = 0;
    return s;
}

static int failures = 0;

#define EXPECT(cond, ...)                                                             \
    do {                                                                              \
        if (!(cond)) {                                                                \
            ++failures;                                                               \
            fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond);           \
            fprintf(stderr, __VA_ARGS__);                                             \
            fputc('\n', stderr);                                                      \
        }                                                                             \
    } while (0)

/* One input, one configuration: the sweep over N. Returns the N reached. */
static long sweep(const char* name, const char* json, size_t len, const ntsj_config* cfg) {
    ntsj_response ref;
    char* ref_body;
    const char* ref_code;
    long n, limit = 200000;
    int rc = ntsj_handle(json, len, cfg, &ref);
    if (rc != 0 || ref.body == NULL) {
        EXPECT(0, "%s: reference run failed (rc %d)", name, rc);
        return 0;
    }
    ref_body = without_elapsed(ref.body);
    ref_code = ref.code;
    ntsj_response_free(&ref);
    for (n = 1; n <= limit; ++n) {
        ntsj_response r;
        int before = failures;
        hooks_on(n);
        rc = ntsj_handle(json, len, cfg, &r);
        EXPECT(rc == 0 || rc == NTS_ENOMEM, "%s N=%ld: rc %d", name, n, rc);
        if (rc == NTS_ENOMEM) {
            EXPECT(r.body == NULL, "%s N=%ld: NTS_ENOMEM with a body", name, n);
            EXPECT(g_fa.failed > 0, "%s N=%ld: NTS_ENOMEM without a refusal", name, n);
        } else if (rc == 0) {
            EXPECT(r.body != NULL && r.code != NULL, "%s N=%ld: no body", name, n);
            if (r.body != NULL && r.code != NULL) {
                if (strcmp(r.code, "out_of_memory") == 0) {
                    EXPECT(g_fa.failed > 0, "%s N=%ld: out_of_memory without a refusal", name, n);
                    EXPECT(r.http_status == 503 && !r.ok, "%s N=%ld: out_of_memory as HTTP %d", name, n,
                           r.http_status);
                    EXPECT(strstr(r.body, "\"out_of_memory\"") != NULL, "%s N=%ld: body %s", name, n, r.body);
                } else {
                    char* got = without_elapsed(r.body);
                    EXPECT(got != NULL && strcmp(got, ref_body) == 0,
                           "%s N=%ld: a refused allocation changed the answer: code %s (reference %s)", name, n,
                           r.code, ref_code);
                    free(got);
                }
            }
        }
        ntsj_response_free(&r);
        EXPECT(g_fa.live == 0, "%s N=%ld: %ld blocks leaked", name, n, g_fa.live);
        {
            long failed = g_fa.failed, leaked = g_fa.live;
            hooks_off();
            if (failures > before + 20 || leaked != 0) break; /* enough reports for one input */
            if (failed == 0) break;                         /* fewer than N allocations: done */
        }
    }
    hooks_off();
    free(ref_body);
    return n;
}

static char* read_file(const char* path, size_t* len) {
    FILE* f = fopen(path, "rb");
    char* buf = NULL;
    long n;
    if (f == NULL) return NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0) {
        buf = (char*)malloc((size_t)n + 1);
        if (buf != NULL && fread(buf, 1, (size_t)n, f) == (size_t)n) {
            buf[n] = 0;
            *len = (size_t)n;
        } else {
            free(buf);
            buf = NULL;
        }
    }
    fclose(f);
    return buf;
}

static long points = 0;
static int inputs = 0;

static void run_file(const char* path) {
    size_t len = 0;
    char* json = read_file(path, &len);
    ntsj_config cfg = ntsj_default_config();
    if (json == NULL) {
        EXPECT(0, "cannot read %s", path);
        return;
    }
    ++inputs;
    cfg.overrides.has_outputs = 1;
    cfg.overrides.outputs = NTS_OUT_ALL;
    points += sweep(path, json, len, &cfg);
    cfg.pretty = 1;
    cfg.mode = NTSJ_VALIDATE;
    points += sweep(path, json, len, &cfg);
    free(json);
}

static int ends_with_json(const char* s) {
    size_t n = strlen(s);
    return n > 5 && strcmp(s + n - 5, ".json") == 0;
}

static int by_name(const void* a, const void* b) { return strcmp(*(char* const*)a, *(char* const*)b); }

static void run_path(const char* path) {
    struct stat st;
    if (stat(path, &st) != 0) {
        EXPECT(0, "no such file or directory: %s", path);
    } else if (S_ISDIR(st.st_mode)) {
        DIR* d = opendir(path);
        struct dirent* e;
        char* names[256];
        size_t n = 0, i;
        while (d != NULL && (e = readdir(d)) != NULL && n < 256) {
            if (!ends_with_json(e->d_name)) continue;
            names[n] = (char*)malloc(strlen(path) + strlen(e->d_name) + 2);
            if (names[n] == NULL) break;
            sprintf(names[n], "%s/%s", path, e->d_name);
            ++n;
        }
        if (d != NULL) closedir(d);
        qsort(names, n, sizeof names[0], by_name);
        for (i = 0; i < n; ++i) {
            run_file(names[i]);
            free(names[i]);
        }
    } else {
        run_file(path);
    }
}

int main(int argc, char** argv) {
    int i;
    /* A malformed request too: its error document must survive the sweep. */
    static const char bad[] = "{\"version\":1,\"options\":{\"penalty\":1},\"bodies\":["
                              "{\"id\":\"a\",\"nodes\":[[0,0],[1,0],[0,1]]},"
                              "{\"id\":\"a\",\"nodes\":[[5,0],[6,0],[5,1]]}]}";
    ntsj_config cfg = ntsj_default_config();
    if (argc < 2) {
        fprintf(stderr, "usage: %s FILE|DIR...\n", argv[0]);
        return 2;
    }
    for (i = 1; i < argc; ++i) run_path(argv[i]);
    points += sweep("duplicate id", bad, sizeof bad - 1, &cfg);
    ++inputs;
    printf("codec_alloc: %d inputs, %ld allocation failure points\n", inputs, points);
    if (failures != 0) printf("codec_alloc: %d failed checks\n", failures);
    return failures == 0 && inputs > 1 ? 0 : 1;
}

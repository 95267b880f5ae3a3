/* The in-process engine's flat calls (codec/include/ntscontact/engine.h),
 * linked against the shared libntscontact_engine.so as a foreign host loads it:
 *   - a contact answer is ntsj_handle's, byte for byte (elapsed_ms aside), and
 *     a validation, a bad document and a made session answer as documented;
 *   - a binary step's header lines are ntsj_binary_headers_of's and agree
 *     with the JSON step at the same positions (energy, contacts);
 *   - a step's parameters and bad positions are the daemon's 400s;
 *   - every allocation failure of contact, session creation and a step gives
 *     NULL or an answer, never a crash, and frees everything (live count 0).
 * Usage: test_engine SCENE.json (a bundled example with contacts). */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/engine.h>

static int failures = 0;

#define EXPECT(cond, ...)                                                   \
    do {                                                                    \
        if (!(cond)) {                                                      \
            ++failures;                                                     \
            fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                   \
            fputc('\n', stderr);                                            \
        }                                                                   \
    } while (0)

static char* read_file(const char* path, size_t* length) {
    FILE* f = fopen(path, "rb");
    char* s;
    long n;
    if (f == NULL || fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        if (f) fclose(f);
        return NULL;
    }
    s = (char*)malloc((size_t)n + 1);
    if (s != NULL && fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        s = NULL;
    }
    fclose(f);
    if (s != NULL) s[n] = '\0';
    *length = (size_t)n;
    return s;
}

/* The text with the value of "elapsed_ms" blanked (malloc'ed). */
static char* without_elapsed(const char* body) {
    const char* key = "\"elapsed_ms\":";
    const char* at = strstr(body, key);
    char* s = (char*)malloc(strlen(body) + 2);
    size_t head;
    const char* tail;
    if (s == NULL) return NULL;
    if (at == NULL) return strcpy(s, body);
    head = (size_t)(at - body) + strlen(key);
    tail = body + head;
    while (*tail && *tail != ',' && *tail != '}') ++tail;
    memcpy(s, body, head);
    s[head] = '#';
    strcpy(s + head + 1, tail);
    return s;
}

/* A number that follows `key` in a text ("NTS-Energy: " or "\"energy\":"). */
static double number_after(const char* text, const char* key) {
    const char* at = strstr(text, key);
    return at != NULL ? strtod(at + strlen(key), NULL) : -1.0;
}

/* ------------------------------------------------------------ allocation failures */

static long g_calls, g_fail_at, g_failed, g_live;

static void* failing_alloc(size_t size, void* user) {
    void* p;
    (void)user;
    if (++g_calls == g_fail_at) {
        ++g_failed;
        return NULL;
    }
    p = malloc(size);
    if (p != NULL) ++g_live;
    return p;
}

static void counting_free(void* p, void* user) {
    (void)user;
    if (p != NULL) --g_live;
    free(p);
}

static void failing_on(long fail_at) {
    g_calls = g_failed = g_live = 0;
    g_fail_at = fail_at;
    nts_set_allocator(failing_alloc, counting_free, NULL);
}

/* Contact, session creation and one binary step, allocation N failing, for
 * N = 1, 2, ... until a run goes through untouched. */
static void allocation_sweep(const char* json, size_t length) {
    long n;
    for (n = 1; n < 100000; ++n) {
        ntsj_engine* e;
        ntsj_answer* a;
        ntsj_session* s = NULL;
        failing_on(n);
        e = ntsj_engine_create(0);
        if (e != NULL) {
            a = ntsj_engine_contact(e, json, length, 0);
            if (a != NULL) {
                EXPECT(ntsj_answer_body(a) != NULL, "N=%ld: an answer without a body", n);
                EXPECT(ntsj_answer_ok(a) || ntsj_answer_status(a) >= 500, "N=%ld: status %d", n,
                       ntsj_answer_status(a));
                ntsj_answer_free(a);
            }
            a = ntsj_engine_session_create(e, json, length, &s);
            EXPECT(a != NULL || s == NULL, "N=%ld: a session without an answer", n);
            if (a != NULL) {
                EXPECT(ntsj_answer_ok(a) == (s != NULL), "N=%ld: ok %d, session %p: %d %s", n, ntsj_answer_ok(a),
                       (void*)s, ntsj_answer_status(a), ntsj_answer_body(a));
                ntsj_answer_free(a);
            }
            if (s != NULL) {
                a = ntsj_engine_step(e, s, NTSJ_STEP_EMPTY, NULL, 0, 1, 0, NULL, NULL);
                if (a != NULL) {
                    if (ntsj_answer_ok(a)) EXPECT(strstr(ntsj_answer_headers(a), "NTS-Energy: ") != NULL, "N=%ld", n);
                    ntsj_answer_free(a);
                }
                ntsj_session_destroy(s);
            }
            ntsj_engine_destroy(e);
        }
        nts_set_allocator(NULL, NULL, NULL);
        EXPECT(g_live == 0, "N=%ld: %ld blocks not freed", n, g_live);
        if (g_failed == 0) break; /* the whole run needed fewer than N allocations */
    }
    EXPECT(n > 20 && n < 100000, "the sweep ended at N=%ld", n);
    printf("engine: allocation failures 1..%ld answered and freed\n", n - 1);
}

int main(int argc, char** argv) {
    size_t length = 0;
    char* json = argc > 1 ? read_file(argv[1], &length) : NULL;
    ntsj_engine* e = ntsj_engine_create(2);
    ntsj_config cfg = ntsj_default_config();
    ntsj_response ref;
    ntsj_session* s = NULL;
    ntsj_answer *a, *b;
    long long counts[5];
    const char* names[1];
    const char* values[1];
    char *x, *y;
    if (json == NULL || e == NULL) {
        fprintf(stderr, "usage: test_engine SCENE.json\n");
        return 2;
    }

    /* Contact: ntsj_handle's bytes. */
    cfg.threads = 2;
    EXPECT(ntsj_handle(json, length, &cfg, &ref) == 0 && ref.ok, "reference");
    a = ntsj_engine_contact(e, json, length, 0);
    EXPECT(a != NULL && ntsj_answer_ok(a) && ntsj_answer_status(a) == 200 && !ntsj_answer_binary(a), "contact");
    x = without_elapsed(ref.body);
    y = without_elapsed(ntsj_answer_body(a));
    EXPECT(strcmp(x, y) == 0 && ntsj_answer_length(a) == strlen(ntsj_answer_body(a)), "not ntsj_handle's bytes");
    EXPECT(strcmp(ntsj_answer_code(a), "ok") == 0 && ntsj_answer_headers(a)[0] == '\0', "code, headers");
    free(x);
    free(y);
    ntsj_answer_free(a);
    ntsj_response_free(&ref);

    a = ntsj_engine_contact(e, json, length, 1);
    EXPECT(a != NULL && ntsj_answer_ok(a) && strstr(ntsj_answer_body(a), "\"valid\":true") != NULL, "validate");
    ntsj_answer_free(a);
    a = ntsj_engine_contact(e, "{\"bodies\": [", 12, 0);
    EXPECT(a != NULL && !ntsj_answer_ok(a) && ntsj_answer_status(a) == 400, "bad json");
    EXPECT(a != NULL && strcmp(ntsj_answer_code(a), "invalid_json") == 0, "code %s", a ? ntsj_answer_code(a) : "");
    ntsj_answer_free(a);
    a = ntsj_engine_contact(e, NULL, 0, 0);
    EXPECT(a != NULL && !ntsj_answer_ok(a) && ntsj_answer_status(a) == 400, "empty body");
    ntsj_answer_free(a);

    /* A session: made, then a binary and a JSON step at the stored positions. */
    a = ntsj_engine_session_create(e, json, length, &s);
    EXPECT(a != NULL && ntsj_answer_ok(a) && s != NULL && ntsj_answer_length(a) == 0, "session");
    ntsj_answer_free(a);
    if (s == NULL) return 1;
    ntsj_engine_session_counts(s, counts);
    EXPECT(counts[0] >= 2 && counts[1] >= counts[2] && counts[2] > 0 && counts[4] > 0, "counts");
    a = ntsj_engine_step(e, s, NTSJ_STEP_EMPTY, NULL, 0, 1, 0, NULL, NULL);
    b = ntsj_engine_step(e, s, NTSJ_STEP_EMPTY, NULL, 0, 0, 0, NULL, NULL);
    EXPECT(a != NULL && ntsj_answer_ok(a) && ntsj_answer_binary(a), "binary step");
    EXPECT(a != NULL && ntsj_answer_length(a) == 16 * (size_t)counts[1], "%zu bytes", a ? ntsj_answer_length(a) : 0);
    EXPECT(b != NULL && ntsj_answer_ok(b) && !ntsj_answer_binary(b), "JSON step");
    if (a != NULL && b != NULL) {
        const char* h = ntsj_answer_headers(a);
        double ea = number_after(h, "NTS-Energy: "), eb = number_after(ntsj_answer_body(b), "\"energy\":");
        EXPECT(memcmp(&ea, &eb, sizeof ea) == 0 && ea > 0.0, "energy %.17g against %.17g", ea, eb);
        EXPECT(number_after(h, "NTS-Contacts: ") == number_after(ntsj_answer_body(b), "\"contacts\":"), "contacts");
        EXPECT(strstr(h, "NTS-Virial: ") != NULL && strstr(h, "NTS-Elapsed-Ms: ") != NULL, "%s", h);
        EXPECT(h[strlen(h) - 1] == '\n', "lines end with a newline");
    }
    ntsj_answer_free(a);
    ntsj_answer_free(b);
    /* The daemon's 400s: a bad parameter, positions of the wrong length. */
    names[0] = "alpha";
    values[0] = "-1";
    a = ntsj_engine_step(e, s, NTSJ_STEP_EMPTY, NULL, 0, 1, 1, names, values);
    EXPECT(a != NULL && !ntsj_answer_ok(a) && ntsj_answer_status(a) == 400, "alpha=-1");
    EXPECT(a != NULL && strstr(ntsj_answer_body(a), "alpha") != NULL, "%s", a ? ntsj_answer_body(a) : "");
    ntsj_answer_free(a);
    a = ntsj_engine_step(e, s, NTSJ_STEP_BINARY, json, 24, 1, 0, NULL, NULL);
    EXPECT(a != NULL && !ntsj_answer_ok(a) && ntsj_answer_status(a) == 400, "24 bytes of positions");
    ntsj_answer_free(a);
    ntsj_engine_session_counts(s, counts);
    EXPECT(counts[3] == 2, "steps %lld (the two answered)", counts[3]);
    ntsj_session_destroy(s);
    ntsj_engine_destroy(e);
    ntsj_engine_destroy(NULL);
    ntsj_answer_free(NULL);

    /* A sized engine: a call or a session's scene over its max_bytes is
     * payload_too_large (413), no session made; at max_bytes it goes. */
    {
        ntsj_engine* small = ntsj_engine_create_sized(0, length - 1);
        ntsj_engine* fits = ntsj_engine_create_sized(0, length);
        ntsj_session* none = NULL;
        EXPECT(small != NULL && fits != NULL, "sized engines");
        a = ntsj_engine_contact(small, json, length, 0);
        EXPECT(a != NULL && ntsj_answer_status(a) == 413 && strcmp(ntsj_answer_code(a), "payload_too_large") == 0,
               "over max_bytes: %d", a != NULL ? ntsj_answer_status(a) : -1);
        ntsj_answer_free(a);
        a = ntsj_engine_session_create(small, json, length, &none);
        EXPECT(a != NULL && ntsj_answer_status(a) == 413 && none == NULL, "a session's scene over max_bytes");
        ntsj_answer_free(a);
        a = ntsj_engine_contact(fits, json, length, 0);
        EXPECT(a != NULL && ntsj_answer_ok(a), "at max_bytes");
        ntsj_answer_free(a);
        ntsj_engine_destroy(small);
        ntsj_engine_destroy(fits);
    }
    allocation_sweep(json, length);
    free(json);
    if (failures == 0) printf("engine: all checks passed\n");
    return failures == 0 ? 0 : 1;
}

/* libFuzzer target (issue 7): decode + evaluate + encode of a scene through
 * ntsj_handle, the one call the CLI and the server make. The input is the
 * request body as it would arrive; each input runs twice, once as an
 * evaluation with the default configuration and once as a validation with
 * tight limits and pretty printing, so both modes and the limit paths are fuzzed.
 *
 * Beyond "no crash, no leak, no undefined behaviour" (the sanitizers) the
 * target checks the response contract on every input and aborts on a breach:
 *   - the body is NUL-terminated, `length` is its strlen, it ends with '\n';
 *   - ok <=> http_status == 200 <=> code == "ok"; errors are 4xx (a 5xx other
 *     than out_of_memory is a bug: the input was never the server's fault);
 *   - the body parses as JSON and never holds NaN, Infinity or null (the
 *     encoder's stand-in for a non-finite number); an error body
 *     is {"error": {"code": <the same code>, ...}}.
 * Each input is also a session step (issue 10) on a small fixed scene: as a
 * JSON step body, and as raw bytes repeated into the 16 N bytes of a binary
 * step (any doubles: NaN, huge, turned-over loops), answered in JSON and in
 * binary; a binary answer must be 16 N bytes of finite doubles.
 * The same file links into the plain replay driver (replay_main.c), which
 * replays the corpus under gcc's sanitizers inside the test suite. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include <ntscontact/codec.h>

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

#define CHECK(cond)                                                                          \
    do {                                                                                     \
        if (!(cond)) {                                                                       \
            fprintf(stderr, "fuzz_handle: contract breached: %s (%s:%d)\n", #cond, __FILE__, \
                    __LINE__);                                                               \
            abort();                                                                         \
        }                                                                                    \
    } while (0)

static void check_response(const ntsj_response* r, int rc) {
    cJSON* doc;
    const char* end = NULL;
    CHECK(rc == 0);
    CHECK(r->body != NULL);
    CHECK(r->code != NULL);
    CHECK(r->length == strlen(r->body));
    CHECK(r->length > 0 && r->body[r->length - 1] == '\n');
    CHECK(r->ok == (r->http_status == 200));
    CHECK(r->ok == (strcmp(r->code, "ok") == 0));
    CHECK(r->ok || (r->http_status >= 400 && r->http_status < 500) || strcmp(r->code, "out_of_memory") == 0);
    doc = cJSON_ParseWithLengthOpts(r->body, r->length, &end, 0);
    CHECK(doc != NULL);
    if (!r->ok) {
        const cJSON* e = cJSON_GetObjectItemCaseSensitive(doc, "error");
        const cJSON* c = cJSON_GetObjectItemCaseSensitive(e, "code");
        CHECK(cJSON_IsObject(e));
        CHECK(cJSON_IsString(c) && strcmp(c->valuestring, r->code) == 0);
        CHECK(cJSON_IsString(cJSON_GetObjectItemCaseSensitive(e, "message")));
    } else {
        CHECK(cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(doc, "summary")) ||
              cJSON_IsObject(doc)); /* validation reports have their own shape */
    }
    cJSON_Delete(doc);
}

/* Numbers in the body are never NaN or Infinity (cJSON would read "nan"
 * neither, but a printer bug could write "-nan", "inf" or "1e+999"): outside
 * strings every bare word is true or false, and every number is made of
 * digits, sign, point and exponent and reads back finite. */
static void check_no_nonfinite(const char* s, size_t n) {
    size_t i = 0;
    while (i < n) {
        char c = s[i];
        if (c == '"') {
            for (++i; i < n && s[i] != '"'; ++i)
                if (s[i] == '\\') ++i;
            ++i;
        } else if (c == '-' || (c >= '0' && c <= '9')) {
            char num[64];
            size_t j = i, k = 0;
            while (j < n && strchr("0123456789+-.eE", s[j]) != NULL) ++j;
            CHECK(j - i < sizeof num);
            for (k = 0; k < j - i; ++k) num[k] = s[i + k];
            num[k] = 0;
            {
                double v = strtod(num, NULL);
                CHECK(v - v == 0.0); /* finite */
            }
            CHECK(j == n || strchr(" \t\r\n,]}", s[j]) != NULL);
            i = j;
        } else if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z')) {
            /* No null either: the encoder writes null for a NaN or an infinity
             * handed to it, and no field of the contract is nullable. */
            CHECK(strncmp(s + i, "true", 4) == 0 || strncmp(s + i, "false", 5) == 0);
            while (i < n && ((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= 'A' && s[i] <= 'Z'))) ++i;
        } else {
            ++i;
        }
    }
}

/* Two squares and a triangle mesh square: loops, triangles and holes are not
 * needed for the step paths, reversals and rebuilds are. */
static const char step_scene[] =
    "{\"options\":{\"penalty\":10,\"alpha\":0.2,\"outputs\":[\"forces\",\"contacts\",\"gaps\"]},\"bodies\":["
    "{\"id\":\"a\",\"nodes\":[[0,0],[1,0],[1,1],[0,1]]},"
    "{\"id\":2,\"nodes\":[[0.9,0.2],[1.9,0.2],[1.9,1.2],[0.9,1.2]]},"
    "{\"id\":\"m\",\"nodes\":[[0,1.05],[1,1.05],[1,2],[0,2]],\"triangles\":[[0,1,2],[0,2,3]]}]}";

static void fuzz_steps(const uint8_t* data, size_t size) {
    ntsj_config cfg = ntsj_default_config();
    ntsj_session* ss = NULL;
    ntsj_response r;
    ntsj_step st;
    char* bin;
    size_t bytes, i;
    int rc, nodes, pass;

    rc = ntsj_session_create(step_scene, sizeof step_scene - 1, &cfg, &ss, &r);
    CHECK(rc == 0 && ss != NULL);
    nodes = ntsj_session_get_info(ss).nodes;
    bytes = 16u * (size_t)nodes;
    memset(&st, 0, sizeof st);
    st.kind = NTSJ_STEP_JSON;
    st.body = (const char*)data;
    st.length = size;
    rc = ntsj_session_step(ss, &st, &cfg, &r);
    check_response(&r, rc);
    check_no_nonfinite(r.body, r.length);
    ntsj_response_free(&r);

    bin = malloc(bytes);
    CHECK(bin != NULL);
    for (i = 0; i < bytes; ++i) bin[i] = size ? (char)data[i % size] : 0;
    for (pass = 0; pass < 2; ++pass) {
        st.kind = NTSJ_STEP_BINARY;
        st.body = bin;
        st.length = bytes;
        st.answer_binary = pass;
        rc = ntsj_session_step(ss, &st, &cfg, &r);
        CHECK(rc == 0 && r.body != NULL);
        if (r.ok && r.binary) {
            CHECK(r.length == bytes);
            for (i = 0; i < bytes; i += 8) {
                double v;
                memcpy(&v, r.body + i, sizeof v);
                CHECK(v - v == 0.0);
            }
        } else {
            check_response(&r, rc);
            check_no_nonfinite(r.body, r.length);
        }
        ntsj_response_free(&r);
        /* The input's bytes as small moves of the stored positions instead:
         * nearby configurations, contacts and reversals rather than NaN. */
        for (i = 0; i + 16 <= bytes; i += 16) {
            double x = (double)(i / 16 % 4 == 1 || i / 16 % 4 == 2) + (double)(signed char)bin[i] / 256.0;
            double y = (double)(i / 16 % 4 >= 2) + (double)(i / 64) * 1.05 + (double)(signed char)bin[i + 8] / 256.0;
            memcpy(bin + i, &x, 8);
            memcpy(bin + i + 8, &y, 8);
        }
    }
    st.kind = NTSJ_STEP_EMPTY;
    st.length = 0;
    st.answer_binary = 0;
    rc = ntsj_session_step(ss, &st, &cfg, &r);
    check_response(&r, rc);
    ntsj_response_free(&r);
    free(bin);
    ntsj_session_destroy(ss);
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    ntsj_config cfg = ntsj_default_config();
    ntsj_response r;
    int rc;

    cfg.vtk = 1; /* the VTK document too: present exactly when the result is */
    rc = ntsj_handle((const char*)data, size, &cfg, &r);
    check_response(&r, rc);
    check_no_nonfinite(r.body, r.length);
    CHECK(r.ok == (r.vtk != NULL));
    CHECK(r.vtk == NULL || (r.vtk_length == strlen(r.vtk) && strstr(r.vtk, "</VTKFile>") != NULL));
    ntsj_response_free(&r);
    cfg.vtk = 0;

    cfg.mode = NTSJ_VALIDATE;
    cfg.pretty = 1;
    cfg.max_depth = 6;
    cfg.max_bytes = 4096;
    cfg.limits.max_bodies = 3;
    cfg.limits.max_nodes_per_body = 64;
    cfg.limits.max_nodes = 96;
    rc = ntsj_handle((const char*)data, size, &cfg, &r);
    check_response(&r, rc);
    check_no_nonfinite(r.body, r.length);
    ntsj_response_free(&r);

    fuzz_steps(data, size);
    return 0;
}

/* Access control: bearer tokens, compared in constant time (the time of a
 * compare does not tell how many leading bytes of a guess were right). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "server.h"

int ntsd_load_tokens(ntsd_config* cfg) {
    FILE* f;
    char line[1024];
    if (cfg->token_file[0] == '\0') return 0;
    f = fopen(cfg->token_file, "r");
    if (f == NULL) {
        fprintf(stderr, "ntscontactd: --token-file %s: cannot open it\n", cfg->token_file);
        return -1;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        size_t n = strlen(line);
        char** grown;
        while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r' || line[n - 1] == ' ' || line[n - 1] == '\t'))
            line[--n] = '\0';
        if (n == 0 || line[0] == '#') continue;
        grown = realloc(cfg->tokens, sizeof(char*) * (size_t)(cfg->token_count + 1));
        if (grown == NULL || (grown[cfg->token_count] = strdup(line)) == NULL) {
            fclose(f);
            fprintf(stderr, "ntscontactd: --token-file: out of memory\n");
            return -1;
        }
        cfg->tokens = grown;
        cfg->token_count++;
    }
    fclose(f);
    if (cfg->token_count == 0) {
        fprintf(stderr, "ntscontactd: --token-file %s holds no token\n", cfg->token_file);
        return -1;
    }
    return 0;
}

void ntsd_free_tokens(ntsd_config* cfg) {
    int i;
    for (i = 0; i < cfg->token_count; ++i) free(cfg->tokens[i]);
    free(cfg->tokens);
    cfg->tokens = NULL;
    cfg->token_count = 0;
}

/* Equal strings, in time that depends on their lengths only. */
static int same_secret(const char* a, size_t na, const char* b, size_t nb) {
    unsigned char diff = (unsigned char)(na != nb);
    size_t i, n = na > nb ? na : nb;
    for (i = 0; i < n; ++i) diff |= (unsigned char)((i < na ? a[i] : 0) ^ (i < nb ? b[i] : 0));
    return diff == 0;
}

int ntsd_authorized(const ntsd_config* cfg, const char* authorization, int* which) {
    const char* given;
    int i, ok = 0, at = -1;
    if (which != NULL) *which = -1;
    if (cfg->token_count == 0) return 1;
    if (authorization == NULL || strncasecmp(authorization, "Bearer ", 7) != 0) return 0;
    given = authorization + 7;
    while (*given == ' ') ++given;
    /* Every token is compared: which one matched does not show in the time
     * (the index is kept by a mask, not a branch). */
    for (i = 0; i < cfg->token_count; ++i) {
        const int same = same_secret(given, strlen(given), cfg->tokens[i], strlen(cfg->tokens[i]));
        ok |= same;
        at = (at & (same - 1)) | (i & -same);
    }
    if (which != NULL) *which = ok ? at : -1;
    return ok;
}

int ntsd_is_trusted_proxy(const ntsd_config* cfg, const char* peer) {
    int i;
    for (i = 0; i < cfg->trusted_proxy_count; ++i)
        if (strcmp(cfg->trusted_proxy[i], peer) == 0) return 1;
    return 0;
}

/* The last address of an X-Forwarded-For list ("a, b, c": c is the one the
 * proxy itself saw; the earlier ones are the client's word), trimmed, into
 * out; 0, or -1 when there is none or it is too long. */
static int last_forwarded(const char* xff, char* out, size_t cap) {
    const char* p = strrchr(xff, ',');
    size_t n;
    p = p != NULL ? p + 1 : xff;
    while (*p == ' ' || *p == '\t') ++p;
    n = strcspn(p, " \t");
    if (n == 0 || n >= cap) return -1;
    memcpy(out, p, n);
    out[n] = '\0';
    return 0;
}

void ntsd_client_key(const ntsd_config* cfg, const char* peer, const char* forwarded_for, int token,
                     char out[NTSD_CLIENT_LEN]) {
    char addr[64];
    if (token >= 0 && token < cfg->token_count) {
        /* FNV-1a, 64 bits: stable across a reload of the token file. */
        unsigned long long h = 14695981039346656037ull;
        const char* t;
        for (t = cfg->tokens[token]; *t; ++t) h = (h ^ (unsigned char)*t) * 1099511628211ull;
        snprintf(out, NTSD_CLIENT_LEN, "token:%016llx", h);
        return;
    }
    if (forwarded_for != NULL && ntsd_is_trusted_proxy(cfg, peer) &&
        last_forwarded(forwarded_for, addr, sizeof addr) == 0) {
        snprintf(out, NTSD_CLIENT_LEN, "addr:%s", addr);
        return;
    }
    snprintf(out, NTSD_CLIENT_LEN, "addr:%s", peer);
}

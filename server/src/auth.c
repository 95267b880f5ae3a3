/* Access control: bearer tokens, compared in constant time (the time of a
 * compare does not tell how many leading bytes of a guess were right), read
 * from --token-file at the start and again at SIGHUP. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "server.h"

int ntsd_read_tokens(const char* path, char*** tokens_out, int* count_out, char* why, size_t cap) {
    FILE* f;
    char line[1024];
    char** tokens = NULL;
    int count = 0;
    f = fopen(path, "r");
    if (f == NULL) {
        snprintf(why, cap, "--token-file %s: cannot open it", path);
        return -1;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        size_t n = strlen(line);
        char** grown;
        while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r' || line[n - 1] == ' ' || line[n - 1] == '\t'))
            line[--n] = '\0';
        if (n == 0 || line[0] == '#') continue;
        grown = realloc(tokens, sizeof(char*) * (size_t)(count + 1));
        if (grown != NULL) tokens = grown;
        if (grown == NULL || (tokens[count] = strdup(line)) == NULL) {
            fclose(f);
            ntsd_free_token_list(tokens, count);
            snprintf(why, cap, "--token-file: out of memory");
            return -1;
        }
        count++;
    }
    fclose(f);
    if (count == 0) {
        free(tokens);
        snprintf(why, cap, "--token-file %s holds no token", path);
        return -1;
    }
    *tokens_out = tokens;
    *count_out = count;
    return 0;
}

void ntsd_free_token_list(char** tokens, int count) {
    int i;
    for (i = 0; i < count; ++i) free(tokens[i]);
    free(tokens);
}

int ntsd_load_tokens(ntsd_config* cfg) {
    char why[600];
    if (cfg->token_file[0] == '\0') return 0;
    if (ntsd_read_tokens(cfg->token_file, &cfg->tokens, &cfg->token_count, why, sizeof why) != 0) {
        fprintf(stderr, "ntscontactd: %s\n", why);
        return -1;
    }
    return 0;
}

void ntsd_free_tokens(ntsd_config* cfg) {
    ntsd_free_token_list(cfg->tokens, cfg->token_count);
    cfg->tokens = NULL;
    cfg->token_count = 0;
}

int ntsd_server_reload_tokens(ntsd_server* s) {
    char why[600];
    char** tokens = NULL;
    char** old;
    int count = 0, old_count;
    if (s->config.token_file[0] == '\0') return 0; /* started without tokens: stays so */
    if (ntsd_read_tokens(s->config.token_file, &tokens, &count, why, sizeof why) != 0) {
        ntsd_log_message("SIGHUP: %s; the %d token(s) loaded before stay", why, s->config.token_count);
        return -1;
    }
    /* The only writer is this thread: it reads the old list without the lock. */
    pthread_rwlock_wrlock(&s->tokens_lock);
    old = s->config.tokens;
    old_count = s->config.token_count;
    s->config.tokens = tokens;
    s->config.token_count = count;
    pthread_rwlock_unlock(&s->tokens_lock);
    ntsd_free_token_list(old, old_count);
    ntsd_log_info("SIGHUP: %d token(s) loaded from --token-file %s", count, s->config.token_file);
    return 0;
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

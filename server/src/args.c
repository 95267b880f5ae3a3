/* ntscontactd command line. */
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <ntscontact/ntscontact.h>
#include "server.h"

static const char usage[] =
    "usage: ntscontactd [--host ADDR] [--port N] [--threads N] [--max-body BYTES]\n"
    "                   [--timeout S] [--max-connections N]\n"
    "                   [--quiet]\n"
    "                   [--max-depth N] [--max-bodies N] [--max-nodes N]\n"
    "                   [--max-nodes-per-body N] [--max-seconds S]\n"
    "                   [--max-sessions N] [--session-ttl S] [--session-memory BYTES]\n"
    "                   [--drain-seconds S] [--max-per-client N] [--log-file PATH]\n"
    "                   [--max-candidates N] [--token-file PATH] [--allow-origin URL]\n"
    "                   [--tls-cert PATH --tls-key PATH] [--header-seconds S]\n"
    "                   [--max-memory BYTES] [--log-format text|json] [--allow-host NAME]\n"
    "                   [--session-id-header NAME]\n"
    "\n"
    "Node-to-segment contact over HTTP (POST /v1/contact, POST /v1/validate,\n"
    "POST /v1/scenes, POST /v1/scenes/{id}/contact, GET and DELETE /v1/scenes/{id},\n"
    "GET /v1/health, GET /v1/schemas/{scene,result,error}, GET /v1/openapi.json).\n"
    "\n"
    "  --host ADDR          numeric IPv4/IPv6 address to bind (default 127.0.0.1)\n"
    "  --port N             TCP port, 0 for any free one (default 8080); the bound\n"
    "                       address is printed on stdout: 'ntscontactd listening on HOST:PORT'\n"
    "  --threads N          evaluations at once, each on its connection's thread\n"
    "                       (default: online cores)\n"
    "  --max-body BYTES     largest request body, suffixes k, M, G (default 64M); larger -> 413\n"
    "  --timeout S          idle connection timeout, and the budget to upload one body (default 30)\n"
    "  --max-connections N  connections served at once; beyond -> 503 (default 256)\n"
    "  --quiet              no per-request log lines on stderr\n"
    "  --max-depth N        JSON nesting depth of a request (default 32); deeper -> 400 too_deep\n"
    "  --max-bodies N       bodies in a scene (default 1000000)      } more -> 400\n"
    "  --max-nodes N        nodes in a scene (default 50000000)      } limit_exceeded,\n"
    "  --max-nodes-per-body N  nodes in one body (default 10000000)  } naming the limit\n"
    ;
/* The service's own options (C99 guarantees string literals of 4095 bytes only). */
static const char usage_service[] =
    "  --drain-seconds S    on SIGTERM, SIGINT, SIGQUIT, SIGUSR1, SIGUSR2 or SIGALRM:\n"
    "                       stop accepting, finish the requests in flight for at\n"
    "                       most S seconds (default 30), exit 0 (1 if abandoned)\n"
    "  --max-per-client N   connections from one address at once (default 64)\n"
    "  --log-format FORMAT  text (default) or json: one object a line, {\"time\",\n"
    "                       \"level\", \"event\": \"request\"|\"message\", ...}\n"
    "  --max-memory BYTES   bodies in flight and the estimated peak of their work\n"
    "                       together (default half the machine's memory); beyond\n"
    "                       -> 503 with Retry-After, a request that alone needs\n"
    "                       more -> 413\n"
    "  --header-seconds S   a connection has S seconds, from its opening or its\n"
    "                       previous request, to send a request's headers, however\n"
    "                       slowly it sends them (default 10, 0 = no limit)\n"
    "  --log-file PATH      the log lines go to PATH (append); SIGHUP reopens it\n"
    "  --token-file PATH    bearer tokens, one a line: every request needs\n"
    "                       'Authorization: Bearer TOKEN' (401 otherwise); health\n"
    "                       without a token says only its status\n"
    "  --allow-origin URL   a browser Origin that may call the service (repeatable);\n"
    "                       a request with any other Origin header gets 403\n"
    "  --allow-host NAME    a name the Host header may give (repeatable; port aside);\n"
    "                       any other Host gets 403 (default: any)\n"
    "  --tls-cert PATH, --tls-key PATH  serve HTTPS (PEM files, GnuTLS)\n"
    "  --max-candidates N   closest points kept per evaluation (default 64 per\n"
    "                       surface node + 1000000); more -> 400 limit_exceeded\n"
    "  --max-seconds S      budget of one request's decode + evaluation + encode,\n"
    "                       0 = none (default 0); over -> 400 limit_exceeded\n"
    "  --session-id-header NAME  behind a proxy that routes sessions by id: a new\n"
    "                       session takes the id this header gives (32-64 URL-safe\n"
    "                       characters; deploy/nginx.conf sends nginx's $request_id).\n"
    "                       Only behind a proxy that always sets it\n"
    "  --max-sessions N     scene sessions held at once (default 64); when full, the\n"
    "                       least recently used idle one is evicted\n"
    "  --session-ttl S      a session unused for S seconds is dropped (default 600)\n"
    "  --session-memory BYTES  memory of all sessions together, suffixes k, M, G\n"
    "                       (default 1G); beyond it the least recently used idle\n"
    "                       sessions are evicted\n"
    "  --help, --version\n";

/* Half the memory this process may use: the machine's, or its cgroup's
 * (a container) when that is smaller. */
size_t ntsd_default_max_memory(void) {
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    unsigned long long total = pages > 0 && page > 0 ? (unsigned long long)pages * (unsigned long long)page
                                                     : (unsigned long long)4 << 30;
    FILE* f = fopen("/sys/fs/cgroup/memory.max", "r");
    if (f != NULL) {
        unsigned long long limit;
        if (fscanf(f, "%llu", &limit) == 1 && limit > 0 && limit < total) total = limit; /* "max": none */
        fclose(f);
    }
    if (total / 2 > (unsigned long long)SIZE_MAX) return SIZE_MAX;
    return (size_t)(total / 2);
}

/* One more name for an allow-list flag (--allow-origin, --allow-host): 0, or
 * -1 with a message when the list is full or the name too long. */
static int add_name(const char* flag, const char* v, char list[NTSD_ALLOW_MAX][256], int* count) {
    if (*count == NTSD_ALLOW_MAX || strlen(v) >= 256) {
        fprintf(stderr, "ntscontactd: %s: at most %d, each under 256 bytes\n", flag, NTSD_ALLOW_MAX);
        return -1;
    }
    strcpy(list[(*count)++], v);
    return 0;
}

ntsd_config ntsd_default_config(void) {
    ntsd_config c;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    memset(&c, 0, sizeof c);
    strcpy(c.host, "127.0.0.1");
    c.port = 8080;
    c.threads = cores > 0 ? (cores > 256 ? 256 : (int)cores) : 1;
    c.codec = ntsj_default_config(); /* limits and budgets of every request */
    c.codec.threads = 0;             /* concurrency comes from requests, not from inside one */
    c.timeout_s = 30;
    c.max_connections = 256;
    c.quiet = 0;
    c.drain_seconds = 30;
    c.max_per_client = 64;
    c.header_seconds = 10;
    c.max_memory = ntsd_default_max_memory();
    c.max_sessions = 64;
    c.session_ttl_s = 600;
    c.session_memory = (size_t)1 << 30;
    return c;
}

/* An unsigned integer in [lo, hi]; `suffixes` allows k/M/G (binary): the
 * codec's parser, shared with the CLI. */
static int parse_unsigned(const char* flag, const char* text, unsigned long long lo,
                          unsigned long long hi, int suffixes, unsigned long long* out) {
    if (ntsj_parse_count(text, suffixes, lo, hi, out) == 0) return 0;
    fprintf(stderr, "ntscontactd: %s: expected an integer in [%llu, %llu], got '%s'\n", flag, lo, hi,
            text ? text : "");
    return -1;
}

int ntsd_parse_args(int argc, char** argv, ntsd_config* cfg) {
    int i;
    for (i = 1; i < argc; i++) {
        const char* a = argv[i];
        const char* v = i + 1 < argc ? argv[i + 1] : NULL;
        unsigned long long n = 0;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            fputs(usage, stdout);
            fputs(usage_service, stdout);
            return 1;
        }
        if (strcmp(a, "--version") == 0) {
            printf("ntscontactd %s (libmicrohttpd %s)\n", NTS_VERSION_STRING, MHD_get_version());
            return 1;
        }
        if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
            cfg->quiet = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "ntscontactd: unknown option or missing value: %s\n%s%s", a, usage, usage_service);
            return -1;
        }
        if (strcmp(a, "--host") == 0) {
            if (strlen(v) >= sizeof cfg->host) {
                fprintf(stderr, "ntscontactd: --host: address too long\n");
                return -1;
            }
            strcpy(cfg->host, v);
        } else if (strcmp(a, "--port") == 0) {
            if (parse_unsigned(a, v, 0, 65535, 0, &n)) return -1;
            cfg->port = (unsigned)n;
        } else if (strcmp(a, "--threads") == 0) {
            if (parse_unsigned(a, v, 1, 1024, 0, &n)) return -1;
            cfg->threads = (int)n;
        } else if (strcmp(a, "--max-body") == 0) {
            if (parse_unsigned(a, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
            cfg->codec.max_bytes = (size_t)n;
        } else if (strcmp(a, "--timeout") == 0) {
            if (parse_unsigned(a, v, 1, 86400, 0, &n)) return -1;
            cfg->timeout_s = (unsigned)n;
        } else if (strcmp(a, "--max-connections") == 0) {
            if (parse_unsigned(a, v, 1, 65536, 0, &n)) return -1;
            cfg->max_connections = (unsigned)n;
        } else if (strcmp(a, "--max-depth") == 0) {
            if (parse_unsigned(a, v, 1, 100000, 0, &n)) return -1;
            cfg->codec.max_depth = (int)n;
        } else if (strcmp(a, "--max-bodies") == 0) {
            if (parse_unsigned(a, v, 1, INT_MAX, 1, &n)) return -1;
            cfg->codec.limits.max_bodies = (int)n;
        } else if (strcmp(a, "--max-sessions") == 0) {
            if (parse_unsigned(a, v, 1, 1000000, 1, &n)) return -1;
            cfg->max_sessions = (int)n;
        } else if (strcmp(a, "--session-ttl") == 0) {
            if (parse_unsigned(a, v, 1, 30 * 86400, 0, &n)) return -1;
            cfg->session_ttl_s = (unsigned)n;
        } else if (strcmp(a, "--session-memory") == 0) {
            if (parse_unsigned(a, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
            cfg->session_memory = (size_t)n;
        } else if (strcmp(a, "--max-nodes-per-body") == 0) {
            if (parse_unsigned(a, v, 1, INT_MAX, 1, &n)) return -1;
            cfg->codec.limits.max_nodes_per_body = (int)n;
        } else if (strcmp(a, "--drain-seconds") == 0) {
            if (parse_unsigned(a, v, 0, 86400, 0, &n)) return -1;
            cfg->drain_seconds = (unsigned)n;
        } else if (strcmp(a, "--log-format") == 0) {
            if (strcmp(v, "json") != 0 && strcmp(v, "text") != 0) {
                fprintf(stderr, "ntscontactd: --log-format: text or json, not %s\n", v);
                return -1;
            }
            cfg->log_json = strcmp(v, "json") == 0;
        } else if (strcmp(a, "--max-memory") == 0) {
            if (parse_unsigned(a, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
            cfg->max_memory = (size_t)n;
        } else if (strcmp(a, "--header-seconds") == 0) {
            if (parse_unsigned(a, v, 0, 86400, 0, &n)) return -1;
            cfg->header_seconds = (unsigned)n;
        } else if (strcmp(a, "--max-per-client") == 0) {
            if (parse_unsigned(a, v, 1, 65536, 0, &n)) return -1;
            cfg->max_per_client = (unsigned)n;
        } else if (strcmp(a, "--token-file") == 0 || strcmp(a, "--tls-cert") == 0 || strcmp(a, "--tls-key") == 0) {
            char* dst = a[2] == 't' && a[3] == 'o' ? cfg->token_file : a[6] == 'c' ? cfg->tls_cert : cfg->tls_key;
            if (strlen(v) >= sizeof cfg->token_file) {
                fprintf(stderr, "ntscontactd: %s: path too long\n", a);
                return -1;
            }
            strcpy(dst, v);
        } else if (strcmp(a, "--allow-origin") == 0) {
            if (add_name(a, v, cfg->allow_origin, &cfg->allow_origin_count)) return -1;
        } else if (strcmp(a, "--session-id-header") == 0) {
            if (strlen(v) == 0 || strlen(v) >= sizeof cfg->session_id_header) {
                fprintf(stderr, "ntscontactd: --session-id-header: a header name under 64 bytes\n");
                return -1;
            }
            strcpy(cfg->session_id_header, v);
        } else if (strcmp(a, "--allow-host") == 0) {
            if (add_name(a, v, cfg->allow_host, &cfg->allow_host_count)) return -1;
        } else if (strcmp(a, "--log-file") == 0) {
            if (strlen(v) >= sizeof cfg->log_file) {
                fprintf(stderr, "ntscontactd: --log-file: path too long\n");
                return -1;
            }
            strcpy(cfg->log_file, v);
        } else if (strcmp(a, "--max-candidates") == 0) {
            if (parse_unsigned(a, v, 1, 1ull << 40, 1, &n)) return -1;
            cfg->codec.max_candidates = (long long)n;
        } else if (strcmp(a, "--max-nodes") == 0) {
            if (parse_unsigned(a, v, 1, 1ull << 40, 1, &n)) return -1;
            cfg->codec.limits.max_nodes = (long long)n;
        } else if (strcmp(a, "--max-seconds") == 0) {
            char* end = NULL;
            double sec;
            errno = 0;
            sec = strtod(v, &end);
            if (errno != 0 || end == v || *end != '\0' || !(sec >= 0.0) || sec > 1e9) {
                fprintf(stderr, "ntscontactd: --max-seconds: expected a number of seconds >= 0, got '%s'\n", v);
                return -1;
            }
            cfg->codec.max_seconds = sec;
        } else {
            fprintf(stderr, "ntscontactd: unknown option: %s\n%s%s", a, usage, usage_service);
            return -1;
        }
        i++;
    }
    if ((cfg->tls_cert[0] == '\0') != (cfg->tls_key[0] == '\0')) {
        fprintf(stderr, "ntscontactd: --tls-cert and --tls-key go together\n");
        return -1;
    }
    return ntsd_load_tokens(cfg) == 0 ? 0 : -1;
}

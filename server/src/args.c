/* ntscontactd command line. */
#include <arpa/inet.h>
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <ntscontact/ntscontact.h>
#include "server.h"

static const char usage[] =
    "usage: ntscontactd [--host ADDR] [--port N] [--threads N] [--max-bytes N]\n"
    "                   [--timeout S] [--max-connections N] [--quiet] [options]\n"
    "\n"
    "Node-to-segment contact over HTTP. Routes (schemas/openapi.json, also served\n"
    "at GET /v1/openapi.json):\n"
    "  POST   /v1/contact              a scene in, a result out\n"
    "  POST   /v1/validate             check a scene only\n"
    "  POST   /v1/scenes               keep a scene for a solver loop (a session)\n"
    "  POST   /v1/scenes/{id}/contact  one step of a session: new positions in\n"
    "  GET    /v1/scenes/{id}          a session's description\n"
    "  GET    /v1/scenes/{id}/surface  its surface nodes (steps with ?nodes=surface)\n"
    "  DELETE /v1/scenes/{id}          drop a session\n"
    "  GET    /v1/health               status, version, build, limits, counters\n"
    "  GET    /metrics                 Prometheus text format\n"
    "  GET    /v1/schemas/{scene,result,error,session}  the JSON Schemas\n"
    "  GET    /v1/openapi.json         the OpenAPI 3.1 document\n"
    "\n"
    "Every option with a value takes it as '--name VALUE' or '--name=VALUE';\n"
    "names are written in full. Counts and sizes take k, M, G suffixes where said.\n"
    "\n"
    "  --host ADDR          numeric IPv4/IPv6 address to bind (default 127.0.0.1)\n"
    "  --port N             TCP port, 0 for any free one (default 8080); the bound\n"
    "                       address is printed on stdout: 'ntscontactd listening on HOST:PORT'\n"
    "  --threads N          evaluations at once, each on its connection's thread\n"
    "                       (default: online cores)\n"
    "  --max-bytes N        largest request body, suffixes k, M, G (default 64M); larger -> 413\n"
    "                       (the CLI's --max-bytes; --max-body, its old name here, is deprecated)\n"
    "  --timeout S          idle connection timeout, and the budget to upload one body (default 30)\n"
    "  --max-connections N  connections served at once (default 256); beyond, a new one\n"
    "                       cuts the slowest open one (503 only when none can be cut)\n"
    "  -q, --quiet          no per-request log lines\n"
    ;
/* The limits of a request (C99 guarantees string literals of 4095 bytes only). */
static const char usage_limits[] =
    "  --max-depth N        JSON nesting depth of a request (default 32, at most 512); deeper -> 400 too_deep\n"
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
    "                       without a token says only its status. SIGHUP reads\n"
    "                       the file again (one that fails to load keeps the tokens)\n"
    "  --allow-origin URL   a browser Origin that may call the service (repeatable):\n"
    "                       its CORS preflight (OPTIONS) gets 204, its answers the\n"
    "                       CORS headers; any other Origin header gets 403\n"
    "  --allow-host NAME    a name the Host header may give (repeatable; port aside);\n"
    "                       any other Host gets 403 (default: any)\n"
    "  --tls-cert PATH, --tls-key PATH  serve HTTPS (PEM files, GnuTLS)\n"
    "  --max-candidates N   closest points kept per evaluation (default 64 per\n"
    "                       surface node + 1000000); more -> 400 limit_exceeded\n"
    "  --max-seconds S      budget of one request's decode + evaluation + encode,\n"
    "                       0 = none (default 60); over -> 400 limit_exceeded\n"
    "  --session-id-header NAME  behind a proxy that routes sessions by id: a new\n"
    "                       session takes the id this header gives (32-64 URL-safe\n"
    "                       characters; deploy/nginx.conf sends nginx's $request_id).\n"
    "                       Only behind a proxy that always sets it\n"
    "  --trusted-proxy ADDR a proxy in front (numeric address, repeatable): its\n"
    "                       requests count as those of the client its\n"
    "                       X-Forwarded-For names last, and its connections are\n"
    "                       not limited per client (the proxy limits its clients)\n"
    "  -h, --help           print this help and exit\n"
    "  -V, --version        print the version and exit\n"
    "\n"
    "exit status: 0 stopped by a signal after draining, 1 could not start or\n"
    "requests abandoned, 2 usage error\n";

/* Scene sessions (C99 guarantees string literals of 4095 bytes only). */
static const char usage_sessions[] =
    "  --max-sessions N     scene sessions held at once (default 64); when full,\n"
    "                       an idle one of the client holding the most is evicted\n"
    "  --max-sessions-per-client N  sessions one client (its token, or without\n"
    "                       tokens its address) holds at once (default a quarter\n"
    "                       of --max-sessions, at least 4); its new one takes the\n"
    "                       place of its own least recently used idle one\n"
    "  --session-ttl S      a session unused for S seconds is dropped (default 600)\n"
    "  --session-memory BYTES  memory of all sessions together, suffixes k, M, G\n"
    "                       (default 1G), what a step grows included: idle\n"
    "                       sessions give back their buffers, then those of the\n"
    "                       client holding the most are evicted; a step that\n"
    "                       alone would need more -> 400 limit_exceeded\n"
    "  A session belongs to the client that created it: 404 for any other.\n";

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
    /* A request's time is bounded by default (issue 23: two brute-force
     * scenes held the evaluation slots as long as they liked): the largest
     * scene --max-bytes admits (64 MiB, 4.6 million nodes) takes about 9 s
     * here, decode to encode (docs/operations.md). */
    c.codec.max_seconds = 60.0;
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

/* The options, each with one name (--max-body: the deprecated old name of
 * --max-bytes); getopt_long takes "--name VALUE" and "--name=VALUE" alike. */
enum {
    OPT_HOST = 256, OPT_PORT, OPT_THREADS, OPT_MAX_BYTES, OPT_MAX_BODY, OPT_TIMEOUT, OPT_MAX_CONNECTIONS,
    OPT_MAX_DEPTH, OPT_MAX_BODIES, OPT_MAX_NODES, OPT_MAX_NODES_PER_BODY, OPT_MAX_SECONDS, OPT_MAX_SESSIONS,
    OPT_SESSION_TTL, OPT_SESSION_MEMORY, OPT_DRAIN_SECONDS, OPT_MAX_PER_CLIENT, OPT_LOG_FILE, OPT_LOG_FORMAT,
    OPT_MAX_CANDIDATES, OPT_TOKEN_FILE, OPT_ALLOW_ORIGIN, OPT_ALLOW_HOST, OPT_TLS_CERT, OPT_TLS_KEY,
    OPT_HEADER_SECONDS, OPT_MAX_MEMORY, OPT_SESSION_ID_HEADER, OPT_TRUSTED_PROXY, OPT_MAX_SESSIONS_PER_CLIENT
};

static const struct option long_options[] = {
    {"host", required_argument, NULL, OPT_HOST},
    {"port", required_argument, NULL, OPT_PORT},
    {"threads", required_argument, NULL, OPT_THREADS},
    {"max-bytes", required_argument, NULL, OPT_MAX_BYTES},
    {"max-body", required_argument, NULL, OPT_MAX_BODY},
    {"timeout", required_argument, NULL, OPT_TIMEOUT},
    {"max-connections", required_argument, NULL, OPT_MAX_CONNECTIONS},
    {"quiet", no_argument, NULL, 'q'},
    {"max-depth", required_argument, NULL, OPT_MAX_DEPTH},
    {"max-bodies", required_argument, NULL, OPT_MAX_BODIES},
    {"max-nodes", required_argument, NULL, OPT_MAX_NODES},
    {"max-nodes-per-body", required_argument, NULL, OPT_MAX_NODES_PER_BODY},
    {"max-seconds", required_argument, NULL, OPT_MAX_SECONDS},
    {"max-sessions", required_argument, NULL, OPT_MAX_SESSIONS},
    {"max-sessions-per-client", required_argument, NULL, OPT_MAX_SESSIONS_PER_CLIENT},
    {"session-ttl", required_argument, NULL, OPT_SESSION_TTL},
    {"session-memory", required_argument, NULL, OPT_SESSION_MEMORY},
    {"drain-seconds", required_argument, NULL, OPT_DRAIN_SECONDS},
    {"max-per-client", required_argument, NULL, OPT_MAX_PER_CLIENT},
    {"log-file", required_argument, NULL, OPT_LOG_FILE},
    {"log-format", required_argument, NULL, OPT_LOG_FORMAT},
    {"max-candidates", required_argument, NULL, OPT_MAX_CANDIDATES},
    {"token-file", required_argument, NULL, OPT_TOKEN_FILE},
    {"allow-origin", required_argument, NULL, OPT_ALLOW_ORIGIN},
    {"allow-host", required_argument, NULL, OPT_ALLOW_HOST},
    {"tls-cert", required_argument, NULL, OPT_TLS_CERT},
    {"tls-key", required_argument, NULL, OPT_TLS_KEY},
    {"header-seconds", required_argument, NULL, OPT_HEADER_SECONDS},
    {"max-memory", required_argument, NULL, OPT_MAX_MEMORY},
    {"session-id-header", required_argument, NULL, OPT_SESSION_ID_HEADER},
    {"trusted-proxy", required_argument, NULL, OPT_TRUSTED_PROXY},
    {"help", no_argument, NULL, 'h'},
    {"version", no_argument, NULL, 'V'},
    {NULL, 0, NULL, 0}};

/* The option in `arg` as written, up to any '=': "--name" (or "-x"). */
static const char* option_name(const char* arg, char* buf, size_t cap) {
    size_t n = strcspn(arg, "=");
    if (arg[0] != '-' || arg[1] != '-') n = 2;
    if (n >= cap) n = cap - 1;
    memcpy(buf, arg, n);
    buf[n] = '\0';
    return buf;
}

/* A path into a fixed buffer: 0, or -1 with a message. */
static int copy_path(const char* flag, const char* v, char* dst, size_t cap) {
    if (strlen(v) >= cap) {
        fprintf(stderr, "ntscontactd: %s: path too long\n", flag);
        return -1;
    }
    strcpy(dst, v);
    return 0;
}

/* One option and its value: 0, or -1 after a message naming it. */
static int apply_option(int c, const char* flag, const char* v, ntsd_config* cfg) {
    unsigned long long n = 0;
    switch (c) {
    case OPT_HOST:
        if (strlen(v) >= sizeof cfg->host) {
            fprintf(stderr, "ntscontactd: --host: address too long\n");
            return -1;
        }
        strcpy(cfg->host, v);
        return 0;
    case OPT_PORT:
        if (parse_unsigned(flag, v, 0, 65535, 0, &n)) return -1;
        cfg->port = (unsigned)n;
        return 0;
    case OPT_THREADS:
        if (parse_unsigned(flag, v, 1, 1024, 0, &n)) return -1;
        cfg->threads = (int)n;
        return 0;
    case OPT_MAX_BODY:
        fprintf(stderr, "ntscontactd: --max-body is deprecated: use --max-bytes (the CLI's name for the same limit)\n");
        /* fall through */
    case OPT_MAX_BYTES:
        if (parse_unsigned(flag, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
        cfg->codec.max_bytes = (size_t)n;
        return 0;
    case OPT_TIMEOUT:
        if (parse_unsigned(flag, v, 1, 86400, 0, &n)) return -1;
        cfg->timeout_s = (unsigned)n;
        return 0;
    case OPT_MAX_CONNECTIONS:
        if (parse_unsigned(flag, v, 1, 65536, 0, &n)) return -1;
        cfg->max_connections = (unsigned)n;
        return 0;
    case OPT_MAX_DEPTH:
        if (parse_unsigned(flag, v, 1, NTSJ_MAX_DEPTH_LIMIT, 0, &n)) return -1;
        cfg->codec.max_depth = (int)n;
        return 0;
    case OPT_MAX_BODIES:
        if (parse_unsigned(flag, v, 1, INT_MAX, 1, &n)) return -1;
        cfg->codec.limits.max_bodies = (int)n;
        return 0;
    case OPT_MAX_SESSIONS:
        if (parse_unsigned(flag, v, 1, 1000000, 1, &n)) return -1;
        cfg->max_sessions = (int)n;
        return 0;
    case OPT_MAX_SESSIONS_PER_CLIENT:
        if (parse_unsigned(flag, v, 1, 1000000, 1, &n)) return -1;
        cfg->max_sessions_per_client = (int)n;
        return 0;
    case OPT_SESSION_TTL:
        if (parse_unsigned(flag, v, 1, 30 * 86400, 0, &n)) return -1;
        cfg->session_ttl_s = (unsigned)n;
        return 0;
    case OPT_SESSION_MEMORY:
        if (parse_unsigned(flag, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
        cfg->session_memory = (size_t)n;
        return 0;
    case OPT_MAX_NODES_PER_BODY:
        if (parse_unsigned(flag, v, 1, INT_MAX, 1, &n)) return -1;
        cfg->codec.limits.max_nodes_per_body = (int)n;
        return 0;
    case OPT_DRAIN_SECONDS:
        if (parse_unsigned(flag, v, 0, 86400, 0, &n)) return -1;
        cfg->drain_seconds = (unsigned)n;
        return 0;
    case OPT_LOG_FORMAT:
        if (strcmp(v, "json") != 0 && strcmp(v, "text") != 0) {
            fprintf(stderr, "ntscontactd: --log-format: text or json, not %s\n", v);
            return -1;
        }
        cfg->log_json = strcmp(v, "json") == 0;
        return 0;
    case OPT_MAX_MEMORY:
        if (parse_unsigned(flag, v, 1, (unsigned long long)SIZE_MAX / 2, 1, &n)) return -1;
        cfg->max_memory = (size_t)n;
        return 0;
    case OPT_HEADER_SECONDS:
        if (parse_unsigned(flag, v, 0, 86400, 0, &n)) return -1;
        cfg->header_seconds = (unsigned)n;
        return 0;
    case OPT_MAX_PER_CLIENT:
        if (parse_unsigned(flag, v, 1, 65536, 0, &n)) return -1;
        cfg->max_per_client = (unsigned)n;
        return 0;
    case OPT_TOKEN_FILE:
        return copy_path(flag, v, cfg->token_file, sizeof cfg->token_file);
    case OPT_TLS_CERT:
        return copy_path(flag, v, cfg->tls_cert, sizeof cfg->tls_cert);
    case OPT_TLS_KEY:
        return copy_path(flag, v, cfg->tls_key, sizeof cfg->tls_key);
    case OPT_LOG_FILE:
        return copy_path(flag, v, cfg->log_file, sizeof cfg->log_file);
    case OPT_ALLOW_ORIGIN:
        return add_name(flag, v, cfg->allow_origin, &cfg->allow_origin_count);
    case OPT_ALLOW_HOST:
        return add_name(flag, v, cfg->allow_host, &cfg->allow_host_count);
    case OPT_TRUSTED_PROXY: {
        unsigned char raw[16];
        if (inet_pton(strchr(v, ':') != NULL ? AF_INET6 : AF_INET, v, raw) != 1) {
            fprintf(stderr, "ntscontactd: --trusted-proxy: a numeric IPv4 or IPv6 address, not '%s'\n", v);
            return -1;
        }
        if (cfg->trusted_proxy_count == NTSD_ALLOW_MAX || strlen(v) >= sizeof cfg->trusted_proxy[0]) {
            fprintf(stderr, "ntscontactd: --trusted-proxy: at most %d\n", NTSD_ALLOW_MAX);
            return -1;
        }
        strcpy(cfg->trusted_proxy[cfg->trusted_proxy_count++], v);
        return 0;
    }
    case OPT_SESSION_ID_HEADER:
        if (strlen(v) == 0 || strlen(v) >= sizeof cfg->session_id_header) {
            fprintf(stderr, "ntscontactd: --session-id-header: a header name under 64 bytes\n");
            return -1;
        }
        strcpy(cfg->session_id_header, v);
        return 0;
    case OPT_MAX_CANDIDATES:
        if (parse_unsigned(flag, v, 1, 1ull << 40, 1, &n)) return -1;
        cfg->codec.max_candidates = (long long)n;
        return 0;
    case OPT_MAX_NODES:
        if (parse_unsigned(flag, v, 1, 1ull << 40, 1, &n)) return -1;
        cfg->codec.limits.max_nodes = (long long)n;
        return 0;
    case OPT_MAX_SECONDS: {
        double sec = -1.0;
        if (ntsj_parse_double(v, &sec) != 0 || !(sec >= 0.0) || sec > 1e9) { /* (a number as JSON writes it) */
            fprintf(stderr, "ntscontactd: --max-seconds: expected a number of seconds >= 0, got '%s'\n", v);
            return -1;
        }
        cfg->codec.max_seconds = sec;
        return 0;
    }
    default:
        return -1;
    }
}

static int usage_error(const char* fmt, const char* arg) {
    fprintf(stderr, "ntscontactd: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n");
    fprintf(stderr, "Try 'ntscontactd --help' for more information.\n");
    return -1;
}

int ntsd_parse_args(int argc, char** argv, ntsd_config* cfg) {
    /* "-": a stray argument comes back as code 1 (this program takes none),
     * in order, whatever POSIXLY_CORRECT says; ":": a missing value is ':'. */
    opterr = 0;
    optind = 1;
    for (;;) {
        const int at = optind; /* argv[at]: the option getopt_long reads now */
        int index = -1, c = getopt_long(argc, argv, "-:hqV", long_options, &index);
        char name[64];
        if (c == -1) break;
        if (c == 1) return usage_error("unexpected argument '%s'", optarg);
        if (c == '?') {
            if (optopt != 0 && at < argc && strncmp(argv[at], "--", 2) == 0)
                return usage_error("option '%s' takes no value", option_name(argv[at], name, sizeof name));
            if (optopt != 0) {
                name[0] = '-';
                name[1] = (char)optopt;
                name[2] = '\0';
                return usage_error("unknown option '%s'", name);
            }
            return usage_error("unknown option '%s'", at < argc ? argv[at] : "?");
        }
        if (c == ':') return usage_error("option '%s' needs a value", option_name(argv[at], name, sizeof name));
        /* Names in full: getopt_long would take an unambiguous abbreviation. */
        if (index >= 0 && strcmp(option_name(argv[at], name, sizeof name) + 2, long_options[index].name) != 0)
            return usage_error("unknown option '%s'", name);
        if (c == 'h') {
            fputs(usage, stdout);
            fputs(usage_limits, stdout);
            fputs(usage_sessions, stdout);
            fputs(usage_service, stdout);
            return 1;
        }
        if (c == 'V') {
            printf("ntscontactd %s (libmicrohttpd %s)\n", NTS_VERSION_STRING, MHD_get_version());
            return 1;
        }
        if (c == 'q') {
            cfg->quiet = 1;
            continue;
        }
        if (apply_option(c, name, optarg, cfg) != 0) {
            fprintf(stderr, "Try 'ntscontactd --help' for more information.\n");
            return -1;
        }
    }
    if (optind < argc) return usage_error("unexpected argument '%s'", argv[optind]); /* after "--" */
    if ((cfg->tls_cert[0] == '\0') != (cfg->tls_key[0] == '\0')) {
        fprintf(stderr, "ntscontactd: --tls-cert and --tls-key go together\n");
        return -1;
    }
    return ntsd_load_tokens(cfg) == 0 ? 0 : -1;
}

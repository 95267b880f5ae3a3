/* ntscontact: evaluate one scene file (schemas/scene.schema.json) and print the
 * result (schemas/result.schema.json). The JSON work is the codec's
 * (ntsj_handle), so the CLI answers exactly as the server does.
 *
 * Exit status: 0 done, 2 usage (bad flags, files that cannot be read or
 * made), 3 invalid input (one line on stderr: code, JSON pointer, message), 1
 * internal error (out of memory, a failed write). */
#define _XOPEN_SOURCE 700 /* fileno, realpath (a build without OpenMP has no -pthread to imply them) */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <ntscontact/codec.h>

enum { EXIT_DONE = 0, EXIT_INTERNAL = 1, EXIT_USAGE = 2, EXIT_INVALID = 3 };

/* The name its messages begin with: the program the user ran. */
#ifdef NTS_CLI_MPI
static const char* const prog = "ntscontact-mpi";
#else
static const char* const prog = "ntscontact";
#endif

static void put_escaped(FILE* f, const char* s, int quote);

/* The CLI's own flags, each once: XX(ID, name, short, value, metavar, section, help). Its
 * options (--alpha ...) are NTS_OPTION_MAP's rows with a flag (tables.h);
 * both make the getopt table and --help (print_usage). */
#define CLI_FLAG_MAP(XX)                                                                                       \
    XX(VALIDATE, "validate", 0, 0, "", OPTIONS, "check the scene only; print a validation summary")            \
    XX(PRETTY, "pretty", 0, 0, "", OPTIONS, "indent the output")                                                \
    XX(OUTPUT, "output", 'o', 1, "FILE", OPTIONS, "write to FILE instead of standard output (- for it)")        \
    XX(FRAMES, "frames", 0, 1, "FILE", OPTIONS,                                                                 \
       "evaluate the scene's topology at many positions without\n"                                              \
       "parsing it again: FILE (- for standard input) holds frames\n"                                           \
       "of 16 N bytes each, N the scene's nodes, little-endian\n"                                               \
       "float64 x then y for every node (bodies in scene order,\n"                                              \
       "nodes in body order); one result per frame, one line\n"                                                 \
       "each (JSON Lines), as POST /v1/scenes/{id}/contact gives")                                              \
    XX(VTK, "vtk", 0, 1, "FILE.vtu", OPTIONS,                                                                   \
       "also write the result for ParaView (VTK XML unstructured\n"                                             \
       "grid: surfaces, forces, contacts with gaps and normals);\n"                                             \
       "with --frames, FILE_000000.vtu, ... and a FILE.pvd series")                                             \
    XX(HISTORY_IN, "history-in", 0, 1, "FILE", OPTIONS,                                                        \
       "friction: go on from the anchors of FILE's \"history\" (a\n"                                               \
       "previous result, or a --history-out file) instead of the\n"                                             \
       "scene's own (docs/model.md 14)")                                                                         \
    XX(HISTORY_OUT, "history-out", 0, 1, "FILE", OPTIONS,                                                      \
       "friction: write the anchors after the evaluation to FILE\n"                                              \
       "as {\"history\": [...]} (with --frames: the committed ones\n"                                           \
       "after the last frame; every frame commits)")                                                            \
    XX(MAX_BYTES, "max-bytes", 0, 1, "N", LIMITS, "largest request (default 64M)")                              \
    XX(MAX_DEPTH, "max-depth", 0, 1, "N", LIMITS, "JSON nesting depth (default 32, at most 512)")               \
    XX(MAX_BODIES, "max-bodies", 0, 1, "N", LIMITS, "bodies in a scene (default 1000000)")                      \
    XX(MAX_NODES, "max-nodes", 0, 1, "N", LIMITS, "nodes in a scene, all bodies (default 50000000)")            \
    XX(MAX_NODES_PER_BODY, "max-nodes-per-body", 0, 1, "N", LIMITS, "nodes in one body (default 10000000)")     \
    XX(MAX_SECONDS, "max-seconds", 0, 1, "S", LIMITS,                                                           \
       "wall-clock budget of the request, 0 = none (default 0);\n"                                              \
       "the evaluation itself is stopped when it passes")                                                       \
    XX(MAX_CANDIDATES, "max-candidates", 0, 1, "N", LIMITS,                                                     \
       "closest points within the search radius kept (default\n"                                                \
       "64 per surface node + 1000000): bounds the memory of\n"                                                 \
       "bodies piled on one spot")                                                                              \
    XX(HELP, "help", 'h', 0, "", LIMITS, "print this help and exit")                                             \
    XX(VERSION, "version", 'V', 0, "", LIMITS, "print the version and exit")

enum cli_section { SECTION_OPTIONS, SECTION_LIMITS };

static const struct cli_flag {
    const char* name;
    int short_name, value;
    const char* metavar;
    enum cli_section section;
    const char* help;
} cli_flags[] = {
#define CLI_XX_(ID, name, short_name, value, meta, section, help) {name, short_name, value, meta, SECTION_##section, help},
    CLI_FLAG_MAP(CLI_XX_)
#undef CLI_XX_
};
enum {
#define CLI_XX_(ID, name, short_name, value, meta, section, help) FLAG_##ID,
    CLI_FLAG_MAP(CLI_XX_)
#undef CLI_XX_
    FLAG_COUNT
};

/* One entry of --help: "  --name META" (with "-x, " before a short name),
 * the help from column 23, continuation lines indented to it. */
static void print_entry(int short_name, const char* name, const char* meta, const char* help) {
    char head[64];
    const char* line = help;
    if (short_name) snprintf(head, sizeof head, "-%c, --%s%s%s", short_name, name, *meta ? " " : "", meta);
    else snprintf(head, sizeof head, "--%s%s%s", name, *meta ? " " : "", meta);
    printf(strlen(head) > 20 ? "  %s  " : "  %-20s ", head);
    for (;;) {
        size_t n = strcspn(line, "\n");
        printf("%.*s\n", (int)n, line);
        if (line[n] == '\0') break;
        line += n + 1;
        printf("%23s", "");
    }
}

/* An option's help: its words, then its range or its value names. */
static void print_option(int id) {
    const nts_option_info* r = nts_option_info_of(id);
    char help[256], tail[160];
    tail[0] = '\0';
    if (r->kind == NTS_OPTION_KIND_NUMBER) {
        nts_option_range_text(id, tail, sizeof tail);
    } else if (r->kind == NTS_OPTION_KIND_ENUM) {
        nts_option_names_text(id, tail, sizeof tail);
    } else if (r->kind == NTS_OPTION_KIND_OUTPUTS) {
        ntsj_output_names_text(NULL, tail, sizeof tail);
    }
    snprintf(help, sizeof help, "%s%s%s%s", r->help, *r->help && *tail ? " " : "", tail,
             r->kind == NTS_OPTION_KIND_OUTPUTS ? "\n(empty: the summary only)" : "");
    print_entry(0, r->flag + 2, r->metavar, help);
}

static void print_usage(void) {
    int k;
#ifdef NTS_CLI_MPI
    fputs("ntscontact-mpi: under mpirun -np N, the answer of ntscontact (below) evaluated\n"
          "across the N ranks, bitwise the same (docs/distributed.md). Rank 0 reads the\n"
          "scene; or each rank reads its own part:\n"
          "  --part PATTERN       rank r reads PATTERN with %d = r (a scene document of its\n"
          "                       bodies, the same \"options\" in every part); the scene is\n"
          "                       the parts' bodies in rank order\n\n",
          stdout);
#endif
    fputs("usage: ntscontact [options] SCENE.json\n"
          "       ntscontact [options] -            (read the scene from standard input)\n"
          "       ntscontact [options] --frames FRAMES.bin SCENE.json\n"
          "\n"
          "Evaluate node-to-segment contact for a scene (schemas/scene.schema.json) and\n"
          "write the result (schemas/result.schema.json) as JSON.\n"
          "\n"
          "options (they override the scene's own \"options\"):\n",
          stdout);
    for (k = 0; k < NTS_OPT_COUNT_; ++k)
        if (nts_option_info_of(k)->doors & NTS_OPTION_DOOR_CLI) print_option(k);
    for (k = 0; k < FLAG_COUNT; ++k)
        if (cli_flags[k].section == SECTION_OPTIONS)
            print_entry(cli_flags[k].short_name, cli_flags[k].name, cli_flags[k].metavar, cli_flags[k].help);
    fputs("\n"
          "limits (a scene past one exits 3 with limit_exceeded, payload_too_large or\n"
          "too_deep, the message naming the limit; counts take k, M, G suffixes):\n",
          stdout);
    for (k = 0; k < FLAG_COUNT; ++k)
        if (cli_flags[k].section == SECTION_LIMITS)
            print_entry(cli_flags[k].short_name, cli_flags[k].name, cli_flags[k].metavar, cli_flags[k].help);
    fputs("\n"
          "Every option with a value takes it as '--name VALUE' or '--name=VALUE';\n"
          "names are written in full. '--' ends the options.\n"
          "\n"
          "exit status: 0 done, 2 usage error (a bad flag, a file that cannot be read\n"
          "or made), 3 invalid input (one line on standard error: code, JSON pointer,\n"
          "message), 1 internal error (out of memory, a write that fails: a full disk).\n"
          "-o's file is cut only when the result is written: a run that fails before\n"
          "leaves it as it was (or removes it, if the run made it); a write that fails\n"
          "removes what it wrote. --frames writes a line a frame as it goes.\n",
          stdout);
}

/* One line on standard error: [frame K: ]code at "pointer": message. */
/* What a result may lack, one line on standard error per warning (the
 * result's "warnings" say it too); `frame` < 0 outside --frames. */
static void print_warnings(const ntsj_response* resp, long long frame) {
    int k;
    for (k = 0; k < resp->warning_count; ++k) {
        const nts_warning* w = &resp->warnings[k];
        if (frame >= 0)
            fprintf(stderr, "%s: frame %lld: warning: %s (%lld): %s\n", prog, frame, nts_warning_name(w->code),
                    w->count, nts_warning_message(w->code));
        else
            fprintf(stderr, "%s: warning: %s (%lld): %s\n", prog, nts_warning_name(w->code), w->count,
                    nts_warning_message(w->code));
    }
}

static int print_error(const ntsj_response* resp, long long frame) {
    char pointer[256], message[512];
    ntsj_error_fields(resp->body, resp->length, pointer, sizeof pointer, message, sizeof message);
    /* The pointer is printed as the inside of a JSON string and control
     * characters are escaped, so the diagnostic stays one parseable line
     * whatever keys the request used. */
    fprintf(stderr, "%s: ", prog);
    if (frame >= 0) fprintf(stderr, "frame %lld: ", frame);
    fprintf(stderr, "%s at \"", resp->code);
    put_escaped(stderr, pointer, 1);
    fputs("\": ", stderr);
    put_escaped(stderr, message, 0);
    fputc('\n', stderr);
    return resp->http_status >= 500 ? EXIT_INTERNAL : EXIT_INVALID;
}

/* A mesh file given where a scene is expected: the kind of mesh it looks like
 * (by its first bytes, or its extension when they say nothing), or NULL. The
 * mesh readers live in the Python package (meshio), which converts. */
static const char* mesh_kind(const char* name, const char* data, size_t length) {
    static const struct { const char* ext; const char* kind; } exts[] = {
        {".msh", "a Gmsh mesh"}, {".vtk", "a legacy VTK file"}, {".vtu", "a VTK XML mesh"},
        {".vtp", "a VTK XML mesh"}, {".xdmf", "an XDMF mesh"}, {".xmf", "an XDMF mesh"}, {".med", "a MED mesh"},
        {".inp", "an Abaqus mesh"}, {".mesh", "a Medit mesh"}, {".stl", "an STL mesh"}, {".obj", "an OBJ mesh"},
        {".off", "an OFF mesh"}, {".ply", "a PLY mesh"}, {".exo", "an Exodus mesh"}, {".e", "an Exodus mesh"},
        {".nas", "a Nastran mesh"}, {".bdf", "a Nastran mesh"}, {".su2", "an SU2 mesh"}, {".h5m", "a MOAB mesh"}};
    size_t i = 0, n = length < 512 ? length : 512, len = name ? strlen(name) : 0, k;
    while (i < n && (data[i] == ' ' || data[i] == '\t' || data[i] == '\r' || data[i] == '\n')) ++i;
    if (i < n && (data[i] == '{' || data[i] == '[')) return NULL; /* JSON: the codec decides */
    if (n - i >= 11 && memcmp(data + i, "$MeshFormat", 11) == 0) return "a Gmsh mesh";
    if (n - i >= 14 && memcmp(data + i, "# vtk DataFile", 14) == 0) return "a legacy VTK file";
    if (n >= 4 && memcmp(data, "\x89HDF", 4) == 0) return "an HDF5 file (MED, XDMF or MOAB mesh data)";
    if (n - i >= 20 && memcmp(data + i, "MeshVersionFormatted", 20) == 0) return "a Medit mesh";
    for (k = i; k + 8 <= n; ++k) {
        if (memcmp(data + k, "<VTKFile", 8) == 0) return "a VTK XML mesh";
        if (memcmp(data + k, "<Xdmf", 5) == 0) return "an XDMF mesh";
    }
    if (n - i >= 8 && (strncmp(data + i, "*Heading", 8) == 0 || strncmp(data + i, "*HEADING", 8) == 0))
        return "an Abaqus mesh";
    for (k = 0; k < sizeof exts / sizeof exts[0]; ++k) {
        size_t m = strlen(exts[k].ext);
        if (len > m) {
            size_t j;
            for (j = 0; j < m; ++j) {
                char c = name[len - m + j];
                if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
                if (c != exts[k].ext[j]) break;
            }
            if (j == m) return exts[k].kind;
        }
    }
    return NULL;
}

static int usage_error(const char* fmt, ...) {
    va_list ap;
    fprintf(stderr, "%s: ", prog);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\nTry '%s --help' for more information.\n", prog);
    return EXIT_USAGE;
}

/* Open a file to read ("-": standard input), refusing what cannot be read as
 * one (a directory) with one line naming it: NULL then, the caller exits 2. */
static FILE* open_input(const char* path) {
    struct stat st;
    FILE* f;
    if (strcmp(path, "-") == 0) return stdin;
    f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "%s: cannot open '%s': %s\n", prog, path, strerror(errno));
        return NULL;
    }
    if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
        fprintf(stderr, "%s: cannot read '%s': %s\n", prog, path, strerror(EISDIR));
        fclose(f);
        return NULL;
    }
    return f;
}

/* A number as a request's JSON writes it, read as the codec reads it: the
 * same text, the same value at every door (ntsj_parse_double). */
static int parse_double(const char* s, double* out) { return s != NULL && ntsj_parse_double(s, out) == 0 ? 0 : -1; }

/* A count in [lo, hi], with an optional binary k/M/G suffix: the codec's
 * parser, shared with the daemon. */
static int parse_count(const char* s, long long lo, long long hi, long long* out) {
    unsigned long long v;
    if (ntsj_parse_count(s, 1, (unsigned long long)lo, (unsigned long long)hi, &v) != 0) return -1;
    *out = (long long)v;
    return 0;
}

/* Write `s` with JSON string escapes for control characters (and for '"' and
 * '\\' when `quote`). */
static void put_escaped(FILE* f, const char* s, int quote) {
    for (; *s; ++s) {
        unsigned char c = (unsigned char)*s;
        if (c < 0x20) fprintf(f, "\\u%04x", c);
        else if (quote && (c == '"' || c == '\\')) fprintf(f, "\\%c", c);
        else fputc(c, f);
    }
}

/* Read all of `f`, at most `limit` + 1 bytes (one more than allowed, so the
 * codec sees the request is too large without us reading gigabytes). NULL on
 * failure, with *read_errno the read's errno (0: out of memory). */
static char* read_all(FILE* f, size_t limit, size_t* length, int* read_errno) {
    size_t cap = 1 << 16, len = 0;
    const size_t most = limit < (size_t)-1 ? limit + 1 : limit; /* bytes we read at most */
    char* buf = (char*)malloc(cap);
    *read_errno = 0;
    if (!buf) return NULL;
    for (;;) {
        size_t want, got;
        if (len == cap) {
            char* p;
            if (cap >= most || cap > (size_t)-1 / 2) break;
            cap *= 2;
            p = (char*)realloc(buf, cap);
            if (!p) {
                free(buf);
                return NULL;
            }
            buf = p;
        }
        want = cap - len;
        if (want > most - len) want = most - len;
        if (want == 0) break;
        errno = 0;
        got = fread(buf + len, 1, want, f);
        len += got;
        if (got < want) break;
    }
    if (ferror(f)) {
        *read_errno = errno ? errno : EIO;
        free(buf);
        return NULL;
    }
    *length = len;
    return buf;
}

/* An output: standard output ("-" or none) or a file, opened where it is
 * (a symlink followed, a FIFO or a device written as such). A file is
 * opened without being cut, so that a run that fails before its result
 * leaves a file that was there as it was (and removes one it made); it is
 * cut when the result is written (out_start). `err` keeps the first
 * write's errno, the reason a failure names. */
typedef struct out_file {
    FILE* f;
    const char* path; /* NULL: standard output */
    int made;         /* 1: the file was not there before */
    int err;
} out_file;

/* 0, or EXIT_USAGE after the message (the file cannot be made or opened).
 * `dash`: "-" (or none) is standard output; else a file named "-" (a side
 * file's name, as it always was). */
static int out_open(out_file* o, const char* path, int dash) {
    struct stat st;
    int fd;
    memset(o, 0, sizeof *o);
    if (dash && (!path || strcmp(path, "-") == 0)) {
        o->f = stdout;
        return 0;
    }
    o->made = stat(path, &st) != 0;
    fd = open(path, O_WRONLY | O_CREAT, 0666);
    if (fd < 0 || (o->f = fdopen(fd, "wb")) == NULL) {
        fprintf(stderr, "%s: cannot write '%s': %s\n", prog, path, strerror(errno));
        if (fd >= 0) close(fd);
        if (fd >= 0 && o->made) unlink(path);
        return EXIT_USAGE;
    }
    o->path = path;
    return 0;
}

/* The result begins: a regular file cut to nothing. */
static void out_start(out_file* o) {
    struct stat st;
    if (o->path != NULL && fstat(fileno(o->f), &st) == 0 && S_ISREG(st.st_mode) && ftruncate(fileno(o->f), 0) != 0)
        o->err = errno;
}

/* n bytes to o, the first failure's errno kept. */
static void out_write(out_file* o, const char* data, size_t n) {
    errno = 0;
    if (fwrite(data, 1, n, o->f) != n && !o->err) o->err = errno ? errno : EIO;
}

/* Close o. `written`: its result is complete; else a file made by this run
 * is removed. A failed write removes a regular file's partial result too.
 * 0, or EXIT_INTERNAL after the message naming the file and the reason. */
static int out_close(out_file* o, int written) {
    struct stat st;
    int regular;
    if (o->f == NULL) return 0;
    if (o->path == NULL) {
        errno = 0;
        if ((fflush(o->f) != 0 || ferror(o->f)) && !o->err) o->err = errno ? errno : EIO;
    } else {
        regular = fstat(fileno(o->f), &st) == 0 && S_ISREG(st.st_mode);
        errno = 0;
        if (ferror(o->f) && !o->err) o->err = errno ? errno : EIO;
        if (fclose(o->f) != 0 && !o->err) o->err = errno ? errno : EIO;
        if (regular && (o->err || (!written && o->made))) unlink(o->path);
    }
    o->f = NULL;
    if (!o->err) return 0;
    fprintf(stderr, "%s: error writing '%s': %s\n", prog, o->path ? o->path : "standard output",
            strerror(o->err));
    return EXIT_INTERNAL;
}

/* A whole file: 0, or EXIT_USAGE / EXIT_INTERNAL after the message. */
static int write_file(const char* path, const char* data, size_t n) {
    out_file o;
    const int rc = out_open(&o, path, 0);
    if (rc != 0) return rc;
    out_start(&o);
    out_write(&o, data, n);
    return out_close(&o, 1);
}

/* FILE.vtu -> FILE_000123.vtu: one file per frame, a series ParaView opens
 * through FILE.pvd. */
static void frame_path(char* out, size_t cap, const char* vtk, long long k) {
    size_t stem = strlen(vtk) - 4;
    snprintf(out, cap, "%.*s_%06lld.vtu", (int)stem, vtk, k);
}

static int write_vtk_frame(const char* vtk, long long k, const ntsj_response* resp) {
    char path[4096];
    if (strlen(vtk) + 16 > sizeof path) {
        fprintf(stderr, "%s: --vtk: file name too long\n", prog);
        return EXIT_USAGE;
    }
    frame_path(path, sizeof path, vtk, k);
    return write_file(path, resp->vtk, resp->vtk_length);
}

static int write_pvd(const char* vtk, long long frames) {
    char path[4096], *text, *at;
    const char* base;
    long long k;
    size_t n = strlen(vtk), cap;
    int rc;
    if (n + 16 > sizeof path) return EXIT_USAGE;
    snprintf(path, sizeof path, "%.*s.pvd", (int)(n - 4), vtk);
    /* The series names its files relative to itself. */
    base = strrchr(vtk, '/');
    base = base ? base + 1 : vtk;
    cap = 128 + (size_t)frames * (strlen(base) + 128);
    if ((text = (char*)malloc(cap)) == NULL) {
        fprintf(stderr, "%s: out of memory writing '%s'\n", prog, path);
        return EXIT_INTERNAL;
    }
    at = text + sprintf(text, "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n");
    for (k = 0; k < frames; ++k) {
        char name[4096];
        frame_path(name, sizeof name, base, k);
        at += sprintf(at, "<DataSet timestep=\"%lld\" part=\"0\" file=\"%s\"/>\n", k, name);
    }
    at += sprintf(at, "</Collection>\n</VTKFile>\n");
    rc = write_file(path, text, (size_t)(at - text));
    free(text);
    return rc;
}

/* --history-out: the anchors after the evaluation ({"history": []} when
 * friction is off: a frictionless contact has none). */
static int write_history(const char* path, const ntsj_response* resp) {
    static const char none[] = "{\"history\":[]}\n";
    return resp->history != NULL ? write_file(path, resp->history, resp->history_length)
                                 : write_file(path, none, sizeof none - 1);
}

/* --frames: one session (the scene parsed once), one step per frame. */
static int run_frames(const char* scene, size_t length, const ntsj_config* cfg, const char* frames,
                      const char* output, const char* vtk, const char* history_out) {
    ntsj_session* ss = NULL;
    ntsj_response resp;
    ntsj_step step;
    FILE* in;
    out_file out;
    char* frame = NULL;
    size_t frame_bytes;
    long long k = 0;
    int status = EXIT_DONE, nodes, write_failed = 0, rc;

    if (ntsj_session_create(scene, length, cfg, &ss, &resp) != 0 && !resp.body) {
        fprintf(stderr, "%s: out_of_memory at \"\": out of memory\n", prog);
        return EXIT_INTERNAL;
    }
    if (ss == NULL) {
        status = print_error(&resp, -1);
        ntsj_response_free(&resp);
        return status;
    }
    nodes = ntsj_session_get_info(ss).nodes;
    frame_bytes = (size_t)nodes * 16u;
    in = open_input(frames);
    if (!in) {
        ntsj_session_destroy(ss);
        return EXIT_USAGE;
    }
    frame = (char*)malloc(frame_bytes);
    rc = frame ? out_open(&out, output, 1) : EXIT_INTERNAL;
    if (rc != 0) {
        if (in != stdin) fclose(in);
        free(frame);
        ntsj_session_destroy(ss);
        return rc;
    }
    /* A line a frame, written as it goes (a stream: a run that stops at
     * frame k leaves the k lines before it, and says so in its status). */
    out_start(&out);
    memset(&step, 0, sizeof step);
    step.kind = NTSJ_STEP_BINARY;
    step.body = frame;
    for (;; ++k) {
        size_t got = fread(frame, 1, frame_bytes, in);
        if (got == 0 && (feof(in) || ferror(in))) break;
        if (got < frame_bytes) {
            fprintf(stderr,
                    "%s: frame %lld: invalid_value at \"\": %s has %lu bytes left, a frame is 16*N = 16 * %d = "
                    "%lu bytes\n", prog, k, frames, (unsigned long)got, nodes, (unsigned long)frame_bytes);
            status = EXIT_INVALID;
            break;
        }
        step.length = got;
        if (ntsj_session_step(ss, &step, cfg, &resp) != 0 && !resp.body) {
            fprintf(stderr, "%s: frame %lld: out_of_memory at \"\": out of memory\n", prog, k);
            status = EXIT_INTERNAL;
            break;
        }
        if (!resp.ok) {
            status = print_error(&resp, k);
            ntsj_response_free(&resp);
            break;
        }
        out_write(&out, resp.body, resp.length);
        write_failed = out.err != 0;
        print_warnings(&resp, k);
        if (vtk && !write_failed && (rc = write_vtk_frame(vtk, k, &resp)) != 0) {
            ntsj_response_free(&resp);
            status = rc;
            break;
        }
        /* the committed anchors after each frame: the last one's stays */
        if (history_out && !write_failed && (rc = write_history(history_out, &resp)) != 0) {
            ntsj_response_free(&resp);
            status = rc;
            break;
        }
        ntsj_response_free(&resp);
        if (write_failed) break;
    }
    if (vtk && k > 0 && status == EXIT_DONE && !write_failed && (rc = write_pvd(vtk, k)) != 0) status = rc;
    if (ferror(in)) {
        fprintf(stderr, "%s: cannot read '%s'\n", prog, frames);
        status = EXIT_USAGE;
    }
    if (in != stdin) fclose(in);
    if (out_close(&out, 1) != 0) status = EXIT_INTERNAL;
    free(frame);
    ntsj_session_destroy(ss);
    return status;
}

/* getopt_long's table, from the two tables: an option of NTS_OPTION_MAP
 * returns OPTION_CODE + its id, a flag its short name or FLAG_CODE + its
 * index. getopt_long takes "--name VALUE" and "--name=VALUE" alike. */
enum { OPTION_CODE = 256, FLAG_CODE = 512 };
static struct option long_options[NTS_OPT_COUNT_ + FLAG_COUNT + 1];

static void make_long_options(void) {
    int k, n = 0;
    for (k = 0; k < NTS_OPT_COUNT_; ++k) {
        const nts_option_info* r = nts_option_info_of(k);
        if (!(r->doors & NTS_OPTION_DOOR_CLI)) continue;
        long_options[n].name = r->flag + 2;
        long_options[n].has_arg = required_argument;
        long_options[n].flag = NULL;
        long_options[n++].val = OPTION_CODE + k;
    }
    for (k = 0; k < FLAG_COUNT; ++k) {
        long_options[n].name = cli_flags[k].name;
        long_options[n].has_arg = cli_flags[k].value ? required_argument : no_argument;
        long_options[n].flag = NULL;
        long_options[n++].val = cli_flags[k].short_name ? cli_flags[k].short_name : FLAG_CODE + k;
    }
    memset(&long_options[n], 0, sizeof long_options[n]);
}

/* An option of the table from its flag's text, into the overrides; 0, or
 * EXIT_USAGE after the message naming the flag. */
static int set_option(ntsj_config* cfg, int id, const char* val) {
    const nts_option_info* r = nts_option_info_of(id);
    nts_option_value v;
    char names[160];
    const char* bad;
    size_t n;
    memset(&v, 0, sizeof v);
    switch (r->kind) {
    case NTS_OPTION_KIND_NUMBER:
        if (parse_double(val, &v.number) != 0) {
            return usage_error("%s needs a number, not '%s'", r->flag, val);
        }
        break;
    case NTS_OPTION_KIND_ENUM: {
        int k;
        for (k = 0; k < r->name_count && strcmp(val, r->names[k]) != 0; ++k) {}
        if (k == r->name_count) {
            nts_option_names_text(id, names, sizeof names);
            return usage_error("%s must be %s, not '%s'", r->flag, names, val);
        }
        v.enumerated = r->values[k];
        break;
    }
    case NTS_OPTION_KIND_OUTPUTS:
        switch (ntsj_output_list(val, 0, &v.flags, &bad, &n)) {
        case 0: break;
        case NTSJ_LIST_DUPLICATE:
            return usage_error("%s lists the output '%.*s' twice: '%s'", r->flag, (int)(n > 32 ? 32 : n), bad, val);
        default:
            ntsj_output_names_text(NULL, names, sizeof names);
            return usage_error("%s takes a comma-separated list of %s, not '%s'", r->flag, names, val);
        }
        break;
    default:
        return usage_error("unknown option '%s'", r->flag);
    }
    ntsj_override_set(&cfg->overrides, id, &v);
    return 0;
}

/* The option at argv[at] as written, up to any '=': "--name" (or "-x"). */
static const char* option_name(const char* arg, char* buf, size_t cap) {
    size_t n = strcspn(arg, "=");
    if (arg[0] != '-' || arg[1] != '-') n = 2; /* a short option: "-x" */
    if (n >= cap) n = cap - 1;
    memcpy(buf, arg, n);
    buf[n] = '\0';
    return buf;
}

/* A count limit: [1, hi], k/M/G suffixes; 0, or EXIT_USAGE after the message. */
static int limit_value(const char* name, const char* val, long long hi, long long* out) {
    long long any;
    if (parse_count(val, 1, hi, out) == 0) return 0;
    if (parse_count(val, 1, 0x7fffffffffffffffLL, &any) == 0 ||
        (val[0] >= '1' && val[0] <= '9' && val[strspn(val, "0123456789")] == '\0')) /* (past 64 bits too) */
        fprintf(stderr, "%s: --%s is at most %lld, not '%s'\n", prog, name, hi, val);
    else
        fprintf(stderr, "%s: --%s needs a positive count, not '%s'\n", prog, name, val);
    fprintf(stderr, "Try '%s --help' for more information.\n", prog);
    return EXIT_USAGE;
}

/* What the command line asked for besides the codec's configuration. */
typedef struct cli_args {
    const char* input;
    const char* output;
    const char* frames;
    const char* vtk;
    const char* history_in;
    const char* history_out;
} cli_args;

/* One flag of CLI_FLAG_MAP and its value: 0, EXIT_USAGE after a message, or
 * -1 for --help and --version (done: exit 0). */
static int apply_flag(int k, const char* val, ntsj_config* cfg, cli_args* a) {
    const char* name = cli_flags[k].name;
    long long n = 0;
    int rc = 0;
    switch (k) {
    case FLAG_HELP: print_usage(); return -1;
    case FLAG_VERSION: printf("ntscontact %s\n", NTS_VERSION_STRING); return -1;
    case FLAG_PRETTY: cfg->pretty = 1; break;
    case FLAG_VALIDATE: cfg->mode = NTSJ_VALIDATE; break;
    case FLAG_OUTPUT: a->output = val; break;
    case FLAG_FRAMES: a->frames = val; break;
    case FLAG_HISTORY_IN: a->history_in = val; break;
    case FLAG_HISTORY_OUT:
        a->history_out = val;
        cfg->history_out = 1;
        break;
    case FLAG_VTK: {
        size_t len = strlen(val);
        if (len < 5 || strcmp(val + len - 4, ".vtu") != 0)
            return usage_error("--vtk needs a file name ending in .vtu, not '%s'", val);
        a->vtk = val;
        cfg->vtk = 1;
        break;
    }
    case FLAG_MAX_SECONDS: {
        double sec;
        if (parse_double(val, &sec) != 0 || sec < 0.0)
            return usage_error("--max-seconds needs a number of seconds >= 0, not '%s'", val);
        cfg->max_seconds = sec;
        break;
    }
    case FLAG_MAX_BYTES:
        if ((rc = limit_value(name, val, 0x7fffffffLL, &n)) == 0) cfg->max_bytes = (size_t)n;
        break;
    case FLAG_MAX_DEPTH:
        if ((rc = limit_value(name, val, NTSJ_MAX_DEPTH_LIMIT, &n)) == 0) cfg->max_depth = (int)n;
        break;
    case FLAG_MAX_BODIES:
        if ((rc = limit_value(name, val, 0x7fffffffLL, &n)) == 0) cfg->limits.max_bodies = (int)n;
        break;
    case FLAG_MAX_NODES:
        if ((rc = limit_value(name, val, 1LL << 40, &n)) == 0) cfg->limits.max_nodes = n;
        break;
    case FLAG_MAX_NODES_PER_BODY:
        if ((rc = limit_value(name, val, 0x7fffffffLL, &n)) == 0) cfg->limits.max_nodes_per_body = (int)n;
        break;
    case FLAG_MAX_CANDIDATES:
        if ((rc = limit_value(name, val, 1LL << 40, &n)) == 0) cfg->max_candidates = n;
        break;
    default: break;
    }
    return rc;
}

/* path's directory made absolute (realpath) and its last name: one
 * spelling of a file that need not exist yet. 0 when the directory is not
 * there either. */
static int canonical(const char* path, char* out, size_t cap) {
    char dir[4096], real[PATH_MAX];
    const char* slash = strrchr(path, '/');
    const char* name = slash ? slash + 1 : path;
    if (slash == NULL) snprintf(dir, sizeof dir, ".");
    else if (slash == path) snprintf(dir, sizeof dir, "/");
    else snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    if (realpath(dir, real) == NULL) return 0;
    return snprintf(out, cap, "%s/%s", real, name) < (int)cap;
}

/* Whether two output paths name one file: the same name, the same device
 * and inode (both there), or the same directory and name (a file to be
 * made: "r.json" and "./r.json"). Standard output ("-") is nobody's file. */
static int same_file(const char* a, const char* b) {
    struct stat sa, sb;
    char ca[PATH_MAX + 256], cb[PATH_MAX + 256];
    if (a == NULL || b == NULL || strcmp(a, "-") == 0 || strcmp(b, "-") == 0) return 0;
    if (strcmp(a, b) == 0) return 1;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    return canonical(a, ca, sizeof ca) && canonical(b, cb, sizeof cb) && strcmp(ca, cb) == 0;
}

/* Read the command line into cfg and a: 0, EXIT_USAGE after a message, or -1
 * when --help or --version answered. */
static int parse_args(int argc, char** argv, ntsj_config* cfg, cli_args* a) {
    make_long_options();
    /* "-": non-options come back in order as code 1, so a scene may come
     * before or after the options whatever POSIXLY_CORRECT says; ":": a
     * missing value is ':' and not '?'. */
    opterr = 0;
    for (;;) {
        const int at = optind; /* argv[at]: the option getopt_long reads now */
        int index = -1, c = getopt_long(argc, argv, "-:ho:V", long_options, &index), k, rc;
        const char* val = optarg;
        char name[64];
        if (c == -1) break;
        if (c == 1) {
            if (a->input) return usage_error("more than one scene given ('%s')", val);
            a->input = val;
            continue;
        }
        if (c == '?') {
            /* An unknown option (or an ambiguous abbreviation), or a value
             * given to an option that takes none. */
            if (optopt != 0 && at < argc && strncmp(argv[at], "--", 2) == 0)
                return usage_error("option '%s' takes no value", option_name(argv[at], name, sizeof name));
            if (optopt != 0 && (at >= argc || strncmp(argv[at], "--", 2) != 0)) {
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
        if (c >= OPTION_CODE && c < OPTION_CODE + NTS_OPT_COUNT_) {
            if ((rc = set_option(cfg, c - OPTION_CODE, val)) != 0) return rc;
            continue;
        }
        for (k = 0; k < FLAG_COUNT; ++k)
            if (c == (cli_flags[k].short_name ? cli_flags[k].short_name : FLAG_CODE + k)) break;
        if ((rc = apply_flag(k, val, cfg, a)) != 0) return rc;
    }
    for (; optind < argc; ++optind) { /* after "--": file names only */
        if (a->input) return usage_error("more than one scene given ('%s')", argv[optind]);
        a->input = argv[optind];
    }
    if (!a->input) return usage_error("%s", "no scene given (a file name, or - for standard input)");
    if (a->frames && strcmp(a->frames, "-") == 0 && strcmp(a->input, "-") == 0)
        return usage_error("%s", "--frames - and a scene from standard input: only one can read it");
    if (a->vtk && cfg->mode == NTSJ_VALIDATE) return usage_error("%s", "--vtk writes a result: not with --validate");
    if (a->history_out && cfg->mode == NTSJ_VALIDATE)
        return usage_error("%s", "--history-out writes a result's anchors: not with --validate");
    if (a->history_in && strcmp(a->history_in, "-") == 0 &&
        ((a->input && strcmp(a->input, "-") == 0) || (a->frames && strcmp(a->frames, "-") == 0)))
        return usage_error("%s", "--history-in - and another input from standard input: only one can read it");
    if (a->frames && (cfg->mode == NTSJ_VALIDATE || cfg->pretty))
        return usage_error("%s", "--frames writes one compact result per line: not with --validate or --pretty");
    {
        /* Two outputs in one file would leave neither whole (--frames
         * writes --vtk's FILE_000000.vtu ..., not FILE itself). */
        const char* name[3] = {"-o", "--vtk", "--history-out"};
        const char* path[3];
        int i, j;
        path[0] = a->output;
        path[1] = a->frames ? NULL : a->vtk;
        path[2] = a->history_out;
        for (i = 0; i < 3; ++i)
            for (j = i + 1; j < 3; ++j)
                if (same_file(path[i], path[j]))
                    return usage_error("%s and %s name the same file '%s': give each its own", name[i], name[j],
                                       path[j]);
    }
    return 0;
}

#ifdef NTS_CLI_MPI
/* ntscontact-mpi (mpi/src/cli_hook.c): rank 0 runs this CLI, evaluating
 * across the ranks; the hook's main calls this one. */
void ntsm_cli_configure(ntsj_config* cfg);
int nts_cli_main(int argc, char** argv);
int nts_cli_flags(int argc, char** argv, ntsj_config* cfg);

/* The hook's --part: the command line read into cfg (and refused with this
 * CLI's own message) before the parts are, so that they are read with its
 * limits (--max-depth). argv ends with a name standing for the scene the
 * parts make. 0, EXIT_USAGE, or -1 when --help or --version answered. */
int nts_cli_flags(int argc, char** argv, ntsj_config* cfg) {
    cli_args args = {NULL, NULL, NULL, NULL, NULL, NULL};
    const int rc = parse_args(argc, argv, cfg, &args);
    optind = 1; /* getopt starts afresh for nts_cli_main (the scan ran to its end; parse_args reads optind before each option) */
    return rc;
}
#define main nts_cli_main
#endif

int main(int argc, char** argv) {
    ntsj_config cfg = ntsj_default_config();
    ntsj_response resp;
    cli_args args = {NULL, NULL, NULL, NULL, NULL, NULL};
    char* history = NULL;
    size_t history_length = 0;
    const char* input;
    const char* output;
    const char* frames;
    const char* vtk;
    FILE* in;
    out_file out;
    char* data;
    size_t length = 0;
    int status, read_errno = 0;

    status = parse_args(argc, argv, &cfg, &args);
    if (status != 0) return status < 0 ? EXIT_DONE : status;
#ifdef NTS_CLI_MPI
    ntsm_cli_configure(&cfg);
#endif
    input = args.input;
    output = args.output;
    frames = args.frames;
    vtk = args.vtk;

    in = open_input(input);
    if (!in) return EXIT_USAGE;
    data = read_all(in, cfg.max_bytes, &length, &read_errno);
    if (in != stdin) fclose(in);
    if (!data && read_errno != 0) { /* the file's fault, not ours */
        fprintf(stderr, "%s: cannot read '%s': %s\n", prog, input, strerror(read_errno));
        return EXIT_USAGE;
    }
    if (!data) {
        fprintf(stderr, "%s: out_of_memory at \"\": out of memory reading '%s'\n", prog, input);
        return EXIT_INTERNAL;
    }

    {
        const char* kind = mesh_kind(strcmp(input, "-") == 0 ? NULL : input, data, length);
        if (kind) {
            const char* shown = strcmp(input, "-") == 0 ? "MESH" : input;
            fprintf(stderr,
                    "%s: invalid_json at \"\": %s looks like %s, not a scene (JSON); convert it first: "
                    ".venv/bin/python -m ntscontact convert %s -o scene.json --penalty EPS (docs/python.md)\n", prog,
                    strcmp(input, "-") == 0 ? "the input" : input, kind, shown);
            free(data);
            return EXIT_INVALID;
        }
    }
    if (args.history_in) { /* the anchors to go on from (friction, §14) */
        FILE* hf = open_input(args.history_in);
        if (!hf) {
            free(data);
            return EXIT_USAGE;
        }
        history = read_all(hf, cfg.max_bytes, &history_length, &read_errno);
        if (hf != stdin) fclose(hf);
        if (!history) {
            fprintf(stderr, "%s: cannot read '%s': %s\n", prog, args.history_in,
                    read_errno ? strerror(read_errno) : "out of memory");
            free(data);
            return read_errno ? EXIT_USAGE : EXIT_INTERNAL;
        }
        cfg.history = history;
        cfg.history_length = history_length;
    }
    if (frames) {
        status = run_frames(data, length, &cfg, frames, output, vtk, args.history_out);
        free(history);
        free(data);
        return status;
    }
    status = ntsj_handle(data, length, &cfg, &resp);
    free(data);
    free(history);
    if (status != 0 || !resp.body) {
        fprintf(stderr, "%s: out_of_memory at \"\": out of memory\n", prog);
        return EXIT_INTERNAL;
    }
    if (!resp.ok) {
        status = print_error(&resp, -1);
        ntsj_response_free(&resp);
        return status;
    }

    /* -o's file opened first (not cut), then the side files, then the
     * result: a file that cannot be opened or a side file that fails
     * leaves -o's file as it was. */
    if ((status = out_open(&out, output, 1)) != 0) {
        ntsj_response_free(&resp);
        return status;
    }
    if ((vtk && (status = write_file(vtk, resp.vtk, resp.vtk_length)) != 0) ||
        (args.history_out && (status = write_history(args.history_out, &resp)) != 0)) {
        out_close(&out, 0);
        ntsj_response_free(&resp);
        return status;
    }
    out_start(&out);
    out_write(&out, resp.body, resp.length);
    status = out_close(&out, 1);
    print_warnings(&resp, -1);
    ntsj_response_free(&resp);
    return status;
}

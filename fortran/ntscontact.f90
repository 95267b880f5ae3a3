! ntscontact for Fortran: the C library (libntscontact, core/include/ntscontact)
! through ISO_C_BINDING, Fortran 2008.
!
! Two layers, as the C API is two:
! - bind(C) derived types that mirror the plain C structs field for field
!   (nts_options, nts_summary, nts_virial, nts_error, nts_limits, and the
!   private ones the wrappers hand to C). Their sizes are checked against the C
!   compiler's before any of them crosses the border (ntsf_layout_ok,
!   fortran/ntscontact_glue.c): a Fortran compiler that pads differently
!   gets a status, not a corrupted heap.
! - The ntsf_* procedures: allocatable arrays in and out, an integer status out
!   (NTS_OK = 0, or a negative NTS_E* code; ntsf_strerror(status) says what it
!   means), and a handle (ntsf_scene) that owns the C scene and its
!   evaluation context until ntsf_scene_destroy.
!
! Indices: every index that this module takes or gives is 1-based (node
! indices in triangles, loops and surfaces, the tangent's rows and columns),
! shifted here from and to the C library's 0-based ones. The tangent's degree
! of freedom of node i (global order: bodies in order, nodes in body order)
! is 2 i - 1 for x and 2 i for y. The one exception is the C error record
! (nts_error) and its message, which are the C library's own: 0-based, as
! every other front end of the library reports them.
!
! Not thread-safe per handle: one ntsf_scene evaluates on one thread at a time
! (its context is reused); separate handles may run at once.
module ntscontact
  use, intrinsic :: iso_c_binding
  implicit none
  private

  ! ------------------------------------------------------------- constants

  ! The C enums. The fields that hold them below are integer(c_int), which is
  ! what C compilers make of these small enums; the layout guard checks that
  ! this one did (ntsf_layout_ok: sizeof(nts_role), sizeof(nts_solver)).
  enum, bind(c)
    enumerator :: NTS_ROLE_BOTH = 0, NTS_ROLE_MASTER = 1, NTS_ROLE_SLAVE = 2
  end enum
  enum, bind(c)
    enumerator :: NTS_SOLVER_CLOSED_FORM = 0, NTS_SOLVER_NEWTON = 1
  end enum
  enum, bind(c)
    enumerator :: NTS_SEARCH_CELLS = 0, NTS_SEARCH_BRUTE_FORCE = 1
  end enum
  enum, bind(c)
    enumerator :: NTS_PENALTY_PER_NODE = 0, NTS_PENALTY_PER_LENGTH = 1
  end enum
  public :: NTS_ROLE_BOTH, NTS_ROLE_MASTER, NTS_ROLE_SLAVE
  public :: NTS_SOLVER_CLOSED_FORM, NTS_SOLVER_NEWTON
  public :: NTS_SEARCH_CELLS, NTS_SEARCH_BRUTE_FORCE
  public :: NTS_PENALTY_PER_NODE, NTS_PENALTY_PER_LENGTH
  ! A contact's master feature (geometry.h's nts_kind) and friction state
  ! (ntscontact.h's nts_friction_state): ntsf_contact%kind and %state.
  integer, parameter, public :: NTS_KIND_SEGMENT = 0, NTS_KIND_CORNER = 1, NTS_KIND_VERTEX = 2
  integer, parameter, public :: NTS_FRICTIONLESS = 0, NTS_STICK = 1, NTS_SLIP = 2

  ! Status codes: base.h's NTS_ERRNO_MAP, in its order (tests/fortran checks
  ! every value against the C table, and that none is missing).
  integer(c_int), parameter, public :: NTS_OK = 0, &
    NTS_ENOMEM = -1, NTS_EINVALID_ARGUMENT = -2, NTS_EINVALID_OPTION = -3, NTS_EEMPTY_SCENE = -4, &
    NTS_ENO_NODES = -5, NTS_ELOOP_TOO_SHORT = -6, NTS_EINDEX_RANGE = -7, NTS_ENODE_REUSED = -8, &
    NTS_ENONFINITE = -9, NTS_EDEGENERATE_SEGMENT = -10, NTS_EZERO_AREA = -11, NTS_ESPIKE = -12, &
    NTS_ENONMANIFOLD = -13, NTS_EDEGENERATE_TRIANGLE = -14, NTS_EBOX_TOO_SMALL = -15, NTS_ELIMIT = -16, &
    NTS_ENO_BOUNDARY = -17, NTS_EINTERNAL = -18, NTS_ERESHAPED = -19, NTS_EOUT_OF_RANGE = -20, &
    NTS_ECANCELLED = -21, NTS_EINVALID_SURFACE = -22, NTS_EINVALID_HISTORY = -23

  ! nts_options%outputs: tables.h's NTS_OUTPUT_MAP, one bit each (combine with ior).
  integer(c_int), parameter, public :: NTS_OUT_FORCES = 1, NTS_OUT_ENERGY = 2, NTS_OUT_VIRIAL = 4, &
    NTS_OUT_CONTACTS = 8, NTS_OUT_GAPS = 16, NTS_OUT_STIFFNESS = 32, NTS_OUT_PRESSURE = 64, NTS_OUT_ALL = 127

  ! ntsf_output%warning_codes: ntscontact.h's NTS_WARNING_MAP.
  integer(c_int), parameter, public :: NTS_WARN_NONE = 0, NTS_WARN_PENETRATION_BEYOND_RADIUS = 1, &
    NTS_WARN_PENETRATION_BEYOND_REACH = 2

  ! ------------------------------------------------- mirrors of the C structs

  type, bind(c), public :: nts_vec2
    real(c_double) :: x, y
  end type nts_vec2

  type, bind(c), public :: nts_virial
    real(c_double) :: xx, yy, xy, yx
  end type nts_virial

  ! The C error record (base.h): 0-based indices, -1 where one does not
  ! apply; option and message NUL-terminated (ntsf_error_message).
  type, bind(c), public :: nts_error
    integer(c_int) :: code, body, loop, loop_pos, node, triangle, corner, item
    character(kind=c_char) :: option(32)
    character(kind=c_char) :: message(192)
  end type nts_error

  type, bind(c), public :: nts_limits
    integer(c_int) :: max_bodies, max_nodes_per_body
    integer(c_long_long) :: max_nodes
  end type nts_limits

  type, bind(c), public :: nts_summary
    integer(c_int) :: bodies, surface_nodes, contacts, gaps, deep_contacts
    real(c_double) :: energy
    type(nts_virial) :: virial
    real(c_double) :: max_penetration
    integer(c_int) :: loops_reversed
    real(c_double) :: search_radius, cell_size, dissipation
    integer(c_int) :: sticking, slipping
  end type nts_summary

  ! nts_default_options() gives every field its default; set what you need.
  ! `outputs` is C's unsigned: the flags fit in its 31 low bits. The pointers
  ! (cancel, history, candidates) are the C library's: give ntsf_evaluate an
  ! ntsf_history or ntsf_candidates instead (it sets them), and leave these null.
  type, bind(c), public :: nts_options
    real(c_double) :: alpha, penalty, search_radius
    integer(c_int) :: solver
    integer(c_int) :: outputs
    integer(c_int) :: search
    integer(c_int) :: threads
    integer(c_int) :: penalty_scaling
    integer(c_long_long) :: max_candidates
    type(c_funptr) :: cancel
    type(c_ptr) :: cancel_user
    real(c_double) :: surface_extension, friction, tangential_penalty
    type(c_ptr) :: history
    type(c_ptr) :: candidates
  end type nts_options

  type, bind(c) :: nts_body_def
    type(c_ptr) :: nodes
    integer(c_int) :: node_count
    type(c_ptr) :: loop_nodes, loop_start
    integer(c_int) :: loop_count
    type(c_ptr) :: triangles
    integer(c_int) :: triangle_count
    integer(c_int) :: role
    integer(c_int) :: has_alpha
    real(c_double) :: alpha
    type(c_ptr) :: reference
    type(c_ptr) :: surface
    integer(c_int) :: surface_count
    integer(c_int) :: has_friction
    real(c_double) :: friction
    integer(c_int) :: self_contact
  end type nts_body_def

  type, bind(c) :: nts_scene_def
    type(c_ptr) :: bodies
    integer(c_int) :: body_count
    real(c_double) :: lx, ly
    type(nts_limits) :: limits
  end type nts_scene_def

  type, bind(c) :: nts_triplets
    type(c_ptr) :: rows, cols, values
    integer(c_int) :: count, size
  end type nts_triplets

  type, bind(c) :: nts_warning
    integer(c_int) :: code
    integer(c_long_long) :: count
  end type nts_warning

  type, bind(c) :: nts_contact
    integer(c_int) :: slave_body, slave_node, master_body, kind, master_count
    integer(c_int) :: master_nodes(3)
    real(c_double) :: weights(3), param, gap
    type(nts_vec2) :: normal, point, force
    type(nts_virial) :: virial
    real(c_double) :: penalty
    type(nts_vec2) :: tangential_force
    real(c_double) :: slip
    integer(c_int) :: state, reserved
  end type nts_contact

  type, bind(c) :: nts_result
    type(nts_summary) :: summary
    type(c_ptr) :: warnings
    integer(c_int) :: warning_count
    type(c_ptr) :: forces, pressure, contacts
    integer(c_int) :: contact_count
    type(c_ptr) :: gaps
    integer(c_int) :: gap_count
    type(nts_triplets) :: stiffness
    type(c_ptr) :: anchors
    integer(c_int) :: anchor_count
  end type nts_result

  type, bind(c) :: nts_csr
    type(c_ptr) :: row_start, cols, values
    integer(c_int) :: nnz, size
  end type nts_csr

  ! What the evaluations did with a kept candidate list (ntsf_candidates_info):
  ! how many used it, how many of those built it, how many needed the cells
  ! of the deep contacts' search all the same, the largest displacement of a
  ! node since the last build, the skin of that build, the masters it kept;
  ! the replays that asked for the masters' lines ahead and those that did
  ! not (a choice of speed alone), and the kept masters that the last build
  ! moved out of the lists that replays try (docs/model.md eq. (32)).
  type, bind(c), public :: nts_candidates_info
    integer(c_long_long) :: evaluations, builds, cell_builds
    real(c_double) :: moved, skin
    integer(c_long_long) :: kept, ahead_replays, plain_replays, pruned
  end type nts_candidates_info

  ! ------------------------------------------------------ the Fortran API

  ! One body, as nts_body_def (ntscontact.h) but with arrays and 1-based node
  ! indices. Give triangles, or loops, or neither (one loop through all nodes
  ! in order). Only `nodes` is required.
  type, public :: ntsf_body
    real(c_double), allocatable :: nodes(:, :)      ! (2, node_count): x and y of each node
    integer(c_int), allocatable :: triangles(:, :)  ! (3, triangle_count): a linear triangle mesh
    integer(c_int), allocatable :: loop_nodes(:)    ! the loops' node indices, one loop after another
    ! loop_count + 1 places in loop_nodes: loop l is loop_nodes(loop_start(l) : loop_start(l + 1) - 1);
    ! not allocated: loop_nodes is one loop
    integer(c_int), allocatable :: loop_start(:)
    ! (2, pair_count): the contact surface's segments (docs/model.md §13); not
    ! allocated: the whole boundary; allocated with no pairs: no surface
    integer(c_int), allocatable :: surface(:, :)
    real(c_double), allocatable :: reference(:, :)  ! (2, node_count): NTS_PENALTY_PER_LENGTH's configuration
    integer(c_int) :: role = NTS_ROLE_BOTH
    logical :: has_alpha = .false.                  ! .true.: `alpha` instead of the options' (walls want 0)
    real(c_double) :: alpha = 0
    logical :: has_friction = .false.               ! .true.: `friction` instead of the options' coefficient
    real(c_double) :: friction = 0
    logical :: self_contact = .false.               ! .true.: its nodes meet its own surface too (docs/model.md §16)
  end type ntsf_body

  ! The context's last evaluation: its C result when it succeeded (its
  ! arrays are the context's until the next evaluation), what
  ! ntsf_history_commit keeps. Held by pointer, so that the copies of a
  ! handle (which share its context) share it too: a commit through any
  ! copy keeps the context's last evaluation, never a stale result whose
  ! arrays a later evaluation has moved.
  type :: scene_last
    type(nts_result) :: r
    logical :: ok = .false.
  end type scene_last

  ! A scene and its evaluation context: from ntsf_scene_create to
  ! ntsf_scene_destroy. No finaliser on purpose: an assignment copies the
  ! handle, and two copies finalised would free the scene twice.
  type, public :: ntsf_scene
    private
    type(c_ptr) :: scene = c_null_ptr
    type(c_ptr) :: context = c_null_ptr
    type(scene_last), pointer :: last => null()
  end type ntsf_scene

  ! A kept candidate list (a Verlet list, docs/model.md §15) for a solver's
  ! loop of evaluations of one scene whose nodes move a little between them:
  ! given to ntsf_evaluate (candidates=), it keeps each slave node's masters
  ! within their reach plus a skin, and is built again only when some node
  ! has moved far enough that it could miss one. The answer is that of an
  ! evaluation without it, bit for bit, always; only the time differs. From
  ! ntsf_candidates_create to ntsf_candidates_destroy (no finaliser, as
  ! ntsf_scene); one per scene and loop.
  type, public :: ntsf_candidates
    private
    type(c_ptr) :: list = c_null_ptr
  end type ntsf_candidates

  ! A friction history (docs/model.md §14): where each contact stuck.
  ! Every evaluation given it (ntsf_evaluate, history=) is a trial from it;
  ! ntsf_history_commit makes an evaluation's anchors the new history (an
  ! explicit loop commits every step, an implicit one the converged
  ! iterate). From ntsf_history_create to ntsf_history_destroy; one per
  ! scene and sequence of steps.
  type, public :: ntsf_history
    private
    type(c_ptr) :: history = c_null_ptr
  end type ntsf_history

  ! A sparse matrix in compressed sparse rows, 1-based: row i holds the
  ! columns col(row_ptr(i) : row_ptr(i + 1) - 1), increasing, each once, and
  ! their values val(...). Duplicates of the C triplets are summed in triplet
  ! order (nts_triplets_to_csr), so the values are the same bits every time.
  type, public :: ntsf_csr
    integer :: n = 0                                ! rows and columns: 2 * node_count
    integer(c_int), allocatable :: row_ptr(:)       ! n + 1
    integer(c_int), allocatable :: col(:)           ! nnz
    real(c_double), allocatable :: val(:)           ! nnz
  end type ntsf_csr

  ! One closest point (nts_contact), its indices 1-based: the slave node and
  ! the master body, the master feature (NTS_KIND_*) and its nodes inside the
  ! master body with their shape functions' weights (0 past master_count),
  ! the parameter (s on a segment, xi on a corner), the signed gap (< 0:
  ! penetrating), the master's outward unit normal and the closest point,
  ! the force on the slave (the whole, with friction's tangential part), its
  ! virial, the penalty, and with friction the tangential force, this step's
  ! slip and the state (NTS_FRICTIONLESS, NTS_STICK, NTS_SLIP).
  type, public :: ntsf_contact
    integer :: slave_body = 0, slave_node = 0, master_body = 0
    integer :: kind = NTS_KIND_SEGMENT
    integer :: master_count = 0
    integer :: master_nodes(3) = 0
    real(c_double) :: weights(3) = 0, param = 0, gap = 0
    real(c_double) :: normal(2) = 0, point(2) = 0, force(2) = 0
    real(c_double) :: virial(4) = 0 ! xx, yy, xy, yx
    real(c_double) :: penalty = 0, tangential_force(2) = 0, slip = 0
    integer :: state = NTS_FRICTIONLESS
  end type ntsf_contact

  ! What an evaluation gives. The arrays are allocated when their output was
  ! asked for (nts_options%outputs) and kept between evaluations when their
  ! shape does not change, so that a solver's loop does not allocate.
  type, public :: ntsf_output
    type(nts_summary) :: summary                    ! energy, virial, contacts, max_penetration, ...
    real(c_double), allocatable :: forces(:, :)     ! (2, node_count), NTS_OUT_FORCES
    real(c_double), allocatable :: pressure(:)      ! (node_count), NTS_OUT_PRESSURE
    type(ntsf_csr) :: tangent                       ! K = d2E/dx2, NTS_OUT_STIFFNESS
    ! What the result may lack (nts_result.warnings): codes (NTS_WARN_*) and
    ! how many contacts each concerns; empty when nothing is missing.
    integer(c_int), allocatable :: warning_codes(:)
    integer(c_long_long), allocatable :: warning_counts(:)
    ! NTS_OUT_CONTACTS: the active contacts (gap < 0); NTS_OUT_GAPS: every
    ! closest point within the search radius and every deeper active one;
    ! each in slave order, then master body
    type(ntsf_contact), allocatable :: contacts(:), gaps(:)
  end type ntsf_output

  public :: nts_default_options, nts_default_limits
  public :: ntsf_scene_create, ntsf_scene_destroy, ntsf_evaluate, ntsf_update_positions
  public :: ntsf_node_count, ntsf_body_count, ntsf_strerror, ntsf_status_name, ntsf_warning_name
  public :: ntsf_error_message, ntsf_layout_ok
  public :: ntsf_candidates_create, ntsf_candidates_destroy, ntsf_candidates_clear, ntsf_candidates_info
  public :: ntsf_history_create, ntsf_history_destroy, ntsf_history_clear, ntsf_history_commit
  public :: ntsf_history_count, ntsf_surface_nodes

  ! --------------------------------------------------------- the C library

  interface
    function nts_default_options() bind(c, name="nts_default_options")
      import :: nts_options
      type(nts_options) :: nts_default_options
    end function nts_default_options

    function nts_default_limits() bind(c, name="nts_default_limits")
      import :: nts_limits
      type(nts_limits) :: nts_default_limits
    end function nts_default_limits

    function c_default_scene_def() bind(c, name="nts_default_scene_def")
      import :: nts_scene_def
      type(nts_scene_def) :: c_default_scene_def
    end function c_default_scene_def

    function c_scene_create(def, err) bind(c, name="nts_scene_create")
      import :: c_ptr, nts_scene_def, nts_error
      type(nts_scene_def), intent(in) :: def
      type(nts_error), intent(out) :: err
      type(c_ptr) :: c_scene_create
    end function c_scene_create

    subroutine c_scene_destroy(scene) bind(c, name="nts_scene_destroy")
      import :: c_ptr
      type(c_ptr), value :: scene
    end subroutine c_scene_destroy

    function c_scene_update_positions(scene, positions, err) bind(c, name="nts_scene_update_positions")
      import :: c_ptr, c_int, c_double, nts_error
      type(c_ptr), value :: scene
      real(c_double), intent(in) :: positions(*)
      type(nts_error), intent(out) :: err
      integer(c_int) :: c_scene_update_positions
    end function c_scene_update_positions

    pure function c_scene_node_count(scene) bind(c, name="nts_scene_node_count")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int) :: c_scene_node_count
    end function c_scene_node_count

    pure function c_scene_body_count(scene) bind(c, name="nts_scene_body_count")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int) :: c_scene_body_count
    end function c_scene_body_count

    function c_context_create() bind(c, name="nts_context_create")
      import :: c_ptr
      type(c_ptr) :: c_context_create
    end function c_context_create

    subroutine c_context_destroy(ctx) bind(c, name="nts_context_destroy")
      import :: c_ptr
      type(c_ptr), value :: ctx
    end subroutine c_context_destroy

    function c_evaluate(ctx, scene, opt, res, err) bind(c, name="nts_evaluate")
      import :: c_ptr, c_int, nts_options, nts_result, nts_error
      type(c_ptr), value :: ctx, scene
      type(nts_options), intent(in) :: opt
      type(nts_result), intent(out) :: res
      type(nts_error), intent(out) :: err
      integer(c_int) :: c_evaluate
    end function c_evaluate

    function c_evaluate_positions(ctx, scene, positions, opt, res, err) bind(c, name="nts_evaluate_positions")
      import :: c_ptr, c_int, c_double, nts_options, nts_result, nts_error
      type(c_ptr), value :: ctx, scene
      real(c_double), intent(in) :: positions(*)
      type(nts_options), intent(in) :: opt
      type(nts_result), intent(out) :: res
      type(nts_error), intent(out) :: err
      integer(c_int) :: c_evaluate_positions
    end function c_evaluate_positions

    function c_evaluate_surface_positions(ctx, scene, positions, opt, res, err) &
      bind(c, name="nts_evaluate_surface_positions")
      import :: c_ptr, c_int, c_double, nts_options, nts_result, nts_error
      type(c_ptr), value :: ctx, scene
      real(c_double), intent(in) :: positions(*)
      type(nts_options), intent(in) :: opt
      type(nts_result), intent(out) :: res
      type(nts_error), intent(out) :: err
      integer(c_int) :: c_evaluate_surface_positions
    end function c_evaluate_surface_positions

    pure function c_scene_surface_node_count(scene) bind(c, name="nts_scene_surface_node_count")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int) :: c_scene_surface_node_count
    end function c_scene_surface_node_count

    pure function c_scene_body_node_offset(scene, body) bind(c, name="nts_scene_body_node_offset")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int), value :: body
      integer(c_int) :: c_scene_body_node_offset
    end function c_scene_body_node_offset

    pure function c_scene_body_loop_count(scene, body) bind(c, name="nts_scene_body_loop_count")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int), value :: body
      integer(c_int) :: c_scene_body_loop_count
    end function c_scene_body_loop_count

    function c_scene_body_loop(scene, body, loop, nodes) bind(c, name="nts_scene_body_loop")
      import :: c_ptr, c_int
      type(c_ptr), value :: scene
      integer(c_int), value :: body, loop
      type(c_ptr), intent(out) :: nodes
      integer(c_int) :: c_scene_body_loop
    end function c_scene_body_loop

    function c_triplets_to_csr(t, csr, err) bind(c, name="nts_triplets_to_csr")
      import :: c_int, nts_triplets, nts_csr, nts_error
      type(nts_triplets), intent(in) :: t
      type(nts_csr), intent(out) :: csr
      type(nts_error), intent(out) :: err
      integer(c_int) :: c_triplets_to_csr
    end function c_triplets_to_csr

    subroutine c_csr_free(csr) bind(c, name="nts_csr_free")
      import :: nts_csr
      type(nts_csr), intent(inout) :: csr
    end subroutine c_csr_free

    pure function c_status_name(status) bind(c, name="nts_status_name")
      import :: c_ptr, c_int
      integer(c_int), value :: status
      type(c_ptr) :: c_status_name
    end function c_status_name

    pure function c_strerror(status) bind(c, name="nts_strerror")
      import :: c_ptr, c_int
      integer(c_int), value :: status
      type(c_ptr) :: c_strerror
    end function c_strerror

    pure function c_warning_name(code) bind(c, name="nts_warning_name")
      import :: c_ptr, c_int
      integer(c_int), value :: code
      type(c_ptr) :: c_warning_name
    end function c_warning_name

    pure function c_strlen(s) bind(c, name="strlen")
      import :: c_ptr, c_size_t
      type(c_ptr), value :: s
      integer(c_size_t) :: c_strlen
    end function c_strlen

    function c_candidates_create(skin) bind(c, name="nts_candidates_create")
      import :: c_ptr, c_double
      real(c_double), value :: skin
      type(c_ptr) :: c_candidates_create
    end function c_candidates_create

    subroutine c_candidates_destroy(list) bind(c, name="nts_candidates_destroy")
      import :: c_ptr
      type(c_ptr), value :: list
    end subroutine c_candidates_destroy

    subroutine c_candidates_clear(list) bind(c, name="nts_candidates_clear")
      import :: c_ptr
      type(c_ptr), value :: list
    end subroutine c_candidates_clear

    pure function c_candidates_get_info(list) bind(c, name="nts_candidates_get_info")
      import :: c_ptr, nts_candidates_info
      type(c_ptr), value :: list
      type(nts_candidates_info) :: c_candidates_get_info
    end function c_candidates_get_info

    function c_history_create() bind(c, name="nts_history_create")
      import :: c_ptr
      type(c_ptr) :: c_history_create
    end function c_history_create

    subroutine c_history_destroy(history) bind(c, name="nts_history_destroy")
      import :: c_ptr
      type(c_ptr), value :: history
    end subroutine c_history_destroy

    subroutine c_history_clear(history) bind(c, name="nts_history_clear")
      import :: c_ptr
      type(c_ptr), value :: history
    end subroutine c_history_clear

    function c_history_commit(history, res) bind(c, name="nts_history_commit")
      import :: c_ptr, c_int, nts_result
      type(c_ptr), value :: history
      type(nts_result), intent(in) :: res
      integer(c_int) :: c_history_commit
    end function c_history_commit

    ! fortran/ntscontact_glue.c: how many anchors a history holds (0 for NULL).
    pure function c_history_count(history) bind(c, name="ntsf_c_history_count")
      import :: c_ptr, c_int
      type(c_ptr), value :: history
      integer(c_int) :: c_history_count
    end function c_history_count

    ! fortran/ntscontact_glue.c: n bytes of the C string src into dest.
    pure subroutine c_copy_string(dest, src, n) bind(c, name="ntsf_c_copy_string")
      import :: c_ptr, c_char, c_size_t
      character(kind=c_char), intent(out) :: dest(*)
      type(c_ptr), value :: src
      integer(c_size_t), value :: n
    end subroutine c_copy_string

    ! fortran/ntscontact_glue.c: sizeof of the C struct number `which`
    ! (the order of layout_names below), 0 past the last.
    function c_layout_sizeof(which) bind(c, name="ntsf_c_sizeof")
      import :: c_int, c_size_t
      integer(c_int), value :: which
      integer(c_size_t) :: c_layout_sizeof
    end function c_layout_sizeof
  end interface

  ! The 0-based copies of one body's index arrays, alive while C reads them.
  type :: body_indices
    integer(c_int), allocatable :: triangles(:), loop_nodes(:), loop_start(:), surface(:)
  end type body_indices

contains

  ! ------------------------------------------------------------- scenes

  ! Create the scene (nts_scene_create: copied, validated, normalised) and
  ! its evaluation context. lx, ly: a periodic box [0, lx) x [0, ly) (both 0
  ! or absent: an open scene). A handle that held a scene gives it up first.
  ! status NTS_OK, or the C library's error (err names the body and node,
  ! 0-based), or NTS_EINVALID_ARGUMENT for an array of the wrong shape.
  subroutine ntsf_scene_create(s, bodies, status, lx, ly, limits, err)
    type(ntsf_scene), intent(inout) :: s
    type(ntsf_body), intent(in), target :: bodies(:)
    integer, intent(out) :: status
    real(c_double), intent(in), optional :: lx, ly
    type(nts_limits), intent(in), optional :: limits
    type(nts_error), intent(out), optional :: err
    type(body_indices), allocatable, target :: work(:)
    type(nts_body_def), allocatable, target :: defs(:)
    type(nts_scene_def) :: def
    type(nts_error) :: e
    character(len=:), allocatable :: detail
    integer :: b

    call ntsf_scene_destroy(s)
    e = no_error()
    if (.not. ntsf_layout_ok(detail)) then
      status = fail(e, NTS_EINTERNAL, -1, "the Fortran module's types do not match the C library's: "//detail)
    else
      allocate (work(size(bodies)), defs(size(bodies)))
      status = NTS_OK
      do b = 1, size(bodies)
        status = body_def_of(bodies(b), b - 1, work(b), defs(b), e)
        if (status /= NTS_OK) exit
      end do
      if (status == NTS_OK) then
        def = c_default_scene_def()
        if (size(defs) > 0) def%bodies = c_loc(defs(1))
        def%body_count = int(size(defs), c_int)
        if (present(lx)) def%lx = lx
        if (present(ly)) def%ly = ly
        if (present(limits)) def%limits = limits
        s%scene = c_scene_create(def, e)
        status = e%code
        if (c_associated(s%scene)) then
          status = NTS_OK
          e = no_error() ! C leaves the record alone on success
          s%context = c_context_create()
          if (c_associated(s%context)) allocate (s%last, stat=b)
          if (.not. (c_associated(s%context) .and. associated(s%last))) then
            call ntsf_scene_destroy(s)
            status = fail(e, NTS_ENOMEM, -1, "out of memory (the evaluation context)")
          end if
        else if (status == NTS_OK) then
          status = fail(e, NTS_EINTERNAL, -1, "nts_scene_create gave no scene and no error")
        end if
      end if
    end if
    if (present(err)) err = e
  end subroutine ntsf_scene_create

  ! The scene and its context are freed; the handle is empty (destroying an
  ! empty one does nothing).
  subroutine ntsf_scene_destroy(s)
    type(ntsf_scene), intent(inout) :: s
    if (c_associated(s%context)) call c_context_destroy(s%context)
    if (c_associated(s%scene)) call c_scene_destroy(s%scene)
    if (associated(s%last)) deallocate (s%last)
    s%context = c_null_ptr
    s%scene = c_null_ptr
    s%last => null()
  end subroutine ntsf_scene_destroy

  ! All nodes of all bodies (0 for an empty handle).
  pure integer function ntsf_node_count(s)
    type(ntsf_scene), intent(in) :: s
    ntsf_node_count = 0
    if (c_associated(s%scene)) ntsf_node_count = c_scene_node_count(s%scene)
  end function ntsf_node_count

  pure integer function ntsf_body_count(s)
    type(ntsf_scene), intent(in) :: s
    ntsf_body_count = 0
    if (c_associated(s%scene)) ntsf_body_count = c_scene_body_count(s%scene)
  end function ntsf_body_count

  ! New positions for every node, (2, node_count) in global order, as a
  ! session's step (nts_scene_update_positions): every check of the scene's
  ! creation on them, and taken only when creating the scene anew from them
  ! would give this very scene. NTS_ERESHAPED: they are valid but change the
  ! scene's normalisation (a loop turned over); create it anew from them.
  ! On any error the scene keeps its positions.
  subroutine ntsf_update_positions(s, positions, status, err)
    type(ntsf_scene), intent(inout) :: s
    real(c_double), intent(in) :: positions(:, :)
    integer, intent(out) :: status
    type(nts_error), intent(out), optional :: err
    type(nts_error) :: e
    e = no_error()
    if (.not. c_associated(s%scene)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no scene (ntsf_scene_create first)")
    else if (size(positions, 1) /= 2 .or. size(positions, 2) /= c_scene_node_count(s%scene)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "positions must be shaped (2, node_count)")
    else
      ! An array section is copied to a contiguous temporary here by the
      ! compiler (assumed-size dummy): C reads 2 * node_count doubles.
      status = c_scene_update_positions(s%scene, positions, e)
      if (status == NTS_OK) e = no_error()
    end if
    if (present(err)) err = e
  end subroutine ntsf_update_positions

  ! ---------------------------------------------------------- evaluation

  ! Evaluate contact at the scene's positions (nts_evaluate) and copy what
  ! `options%outputs` asks for into `out`. On an error `out` holds nothing
  ! (its summary zero, its arrays deallocated). With `positions` ((2,
  ! node_count), global order) a solver's step in one call
  ! (nts_evaluate_positions): ntsf_update_positions then the evaluation, the
  ! same answer and errors, the positions checked in the evaluation's own
  ! pass over the segments; refused positions leave the scene as it was.
  ! With `surface_only` .true. as well, only the loops' nodes of `positions`
  ! are read and taken (ntsf_surface_nodes; nts_evaluate_surface_positions):
  ! a mesh's interior nodes keep their stored positions, their entries may
  ! hold anything, and the step costs what the surface costs.
  ! With `candidates` (created, not destroyed) the evaluation keeps or
  ! replays that kept candidate list, and with `history` it is a trial from
  ! that friction history (options%candidates and options%history are set
  ! from them, in a copy of `options`).
  subroutine ntsf_evaluate(s, options, out, status, err, positions, candidates, history, surface_only)
    type(ntsf_scene), intent(inout) :: s
    type(nts_options), intent(in) :: options
    type(ntsf_output), intent(inout) :: out
    integer, intent(out) :: status
    type(nts_error), intent(out), optional :: err
    real(c_double), intent(in), optional :: positions(:, :)
    type(ntsf_candidates), intent(inout), optional :: candidates
    type(ntsf_history), intent(in), optional :: history
    logical, intent(in), optional :: surface_only
    type(nts_options) :: o
    logical :: surface, no_list, no_history
    type(nts_result) :: r
    type(nts_error) :: e
    type(nts_warning), pointer :: w(:)
    real(c_double), pointer :: f(:, :), p(:)
    integer :: n

    e = no_error()
    ! (Fortran's .and. need not stop at an absent optional argument: it is
    ! tested alone first; `present(x) .and. x%...` read NULL at -O0.)
    no_list = .false.
    if (present(candidates)) no_list = .not. c_associated(candidates%list)
    no_history = .false.
    if (present(history)) no_history = .not. c_associated(history%history)
    if (associated(s%last)) s%last%ok = .false.
    surface = .false.
    if (present(surface_only)) surface = surface_only
    o = options
    if (present(candidates)) o%candidates = candidates%list
    if (present(history)) o%history = history%history
    if (.not. c_associated(s%scene)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no scene (ntsf_scene_create first)")
    else if (no_list) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no candidate list (ntsf_candidates_create first)")
    else if (no_history) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no history (ntsf_history_create first)")
    else if (.not. present(positions)) then
      if (surface) then
        status = fail(e, NTS_EINVALID_ARGUMENT, -1, "surface_only needs positions")
      else
        status = c_evaluate(s%context, s%scene, o, r, e)
      end if
    else if (size(positions, 1) /= 2 .or. size(positions, 2) /= c_scene_node_count(s%scene)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "positions must be shaped (2, node_count)")
    else if (surface) then
      status = c_evaluate_surface_positions(s%context, s%scene, positions, o, r, e)
    else
      status = c_evaluate_positions(s%context, s%scene, positions, o, r, e)
    end if
    if (status == NTS_OK) then
      e = no_error()
      s%last%r = r
      s%last%ok = .true.
      n = ntsf_node_count(s)
      out%summary = r%summary
      ! Assignment reallocates only when the shape changed (Fortran 2003).
      if (c_associated(r%forces)) then
        call c_f_pointer(r%forces, f, [2, n])
        out%forces = f
      else if (allocated(out%forces)) then
        deallocate (out%forces)
      end if
      if (c_associated(r%pressure)) then
        call c_f_pointer(r%pressure, p, [n])
        out%pressure = p
      else if (allocated(out%pressure)) then
        deallocate (out%pressure)
      end if
      if (r%warning_count > 0) then
        call c_f_pointer(r%warnings, w, [r%warning_count])
        out%warning_codes = w%code
        out%warning_counts = w%count
      else
        out%warning_codes = [integer(c_int) ::]
        out%warning_counts = [integer(c_long_long) ::]
      end if
      call contacts_of(r%contacts, r%contact_count, iand(options%outputs, NTS_OUT_CONTACTS) /= 0, out%contacts)
      call contacts_of(r%gaps, r%gap_count, iand(options%outputs, NTS_OUT_GAPS) /= 0, out%gaps)
      if (iand(options%outputs, NTS_OUT_STIFFNESS) /= 0) then
        status = csr_of(r%stiffness, out%tangent, e)
      else
        call clear_csr(out%tangent)
      end if
    end if
    if (status /= NTS_OK) call clear_output(out)
    if (present(err)) err = e
  end subroutine ntsf_evaluate

  ! The nodes contact reads: every node of the scene's loops (a mesh's
  ! boundary, every node of a polygon), as 1-based global node indices, body
  ! by body and loop by loop in each loop's order. The other nodes (a mesh's
  ! interior) get no force. Empty for an empty handle.
  subroutine ntsf_surface_nodes(s, nodes)
    type(ntsf_scene), intent(in) :: s
    integer(c_int), allocatable, intent(out) :: nodes(:)
    integer(c_int), pointer :: loop(:)
    type(c_ptr) :: p
    integer(c_int) :: b, l, m
    integer :: at
    if (.not. c_associated(s%scene)) then
      allocate (nodes(0))
      return
    end if
    ! (the scene's surface nodes are its loops' entries, each once)
    allocate (nodes(c_scene_surface_node_count(s%scene)))
    at = 0
    do b = 0, c_scene_body_count(s%scene) - 1
      do l = 0, c_scene_body_loop_count(s%scene, b) - 1
        m = c_scene_body_loop(s%scene, b, l, p)
        call c_f_pointer(p, loop, [m])
        nodes(at + 1:at + m) = loop + c_scene_body_node_offset(s%scene, b) + 1 ! global, 1-based
        at = at + m
      end do
    end do
  end subroutine ntsf_surface_nodes

  ! ---------------------------------------------------- kept candidates

  ! An empty kept candidate list, built by the first evaluation given it.
  ! skin: the margin beyond the search radius, a length >= 0 (absent: 0.3
  ! times the search radius at each build, the default). A handle that held
  ! a list gives it up first. status NTS_OK, NTS_EINVALID_ARGUMENT (a skin
  ! that is negative, above 1e300 or not a number) or NTS_ENOMEM.
  subroutine ntsf_candidates_create(kc, status, skin, err)
    type(ntsf_candidates), intent(inout) :: kc
    integer, intent(out) :: status
    real(c_double), intent(in), optional :: skin
    type(nts_error), intent(out), optional :: err
    type(nts_error) :: e
    real(c_double) :: margin
    call ntsf_candidates_destroy(kc)
    e = no_error()
    margin = -1 ! C's default: 0.3 times the search radius at each build
    status = NTS_OK
    if (present(skin)) then
      ! (written so that a NaN fails it too)
      if (skin >= 0 .and. skin <= 1.0e300_c_double) then
        margin = skin
      else
        status = fail(e, NTS_EINVALID_ARGUMENT, -1, "skin must be a length >= 0 and at most 1e300")
      end if
    end if
    if (status == NTS_OK) then
      kc%list = c_candidates_create(margin)
      if (.not. c_associated(kc%list)) status = fail(e, NTS_ENOMEM, -1, "out of memory (the candidate list)")
    end if
    if (present(err)) err = e
  end subroutine ntsf_candidates_create

  ! The list is freed; the handle is empty (destroying an empty one does nothing).
  subroutine ntsf_candidates_destroy(kc)
    type(ntsf_candidates), intent(inout) :: kc
    if (c_associated(kc%list)) call c_candidates_destroy(kc%list)
    kc%list = c_null_ptr
  end subroutine ntsf_candidates_destroy

  ! Forget the lists (the next evaluation builds them); its counts stay.
  subroutine ntsf_candidates_clear(kc)
    type(ntsf_candidates), intent(inout) :: kc
    if (c_associated(kc%list)) call c_candidates_clear(kc%list)
  end subroutine ntsf_candidates_clear

  ! What the evaluations did with the list (all zero for an empty handle).
  pure function ntsf_candidates_info(kc) result(info)
    type(ntsf_candidates), intent(in) :: kc
    type(nts_candidates_info) :: info
    info = c_candidates_get_info(kc%list) ! (C's answer for NULL: all zero)
  end function ntsf_candidates_info

  ! ---------------------------------------------------- friction history

  ! An empty friction history (no contact stuck yet). A handle that held
  ! one gives it up first. status NTS_OK or NTS_ENOMEM.
  subroutine ntsf_history_create(h, status)
    type(ntsf_history), intent(inout) :: h
    integer, intent(out) :: status
    call ntsf_history_destroy(h)
    h%history = c_history_create()
    status = NTS_OK
    if (.not. c_associated(h%history)) status = NTS_ENOMEM
  end subroutine ntsf_history_create

  ! The history is freed; the handle is empty (destroying an empty one does nothing).
  subroutine ntsf_history_destroy(h)
    type(ntsf_history), intent(inout) :: h
    if (c_associated(h%history)) call c_history_destroy(h%history)
    h%history = c_null_ptr
  end subroutine ntsf_history_destroy

  ! Forget every committed anchor.
  subroutine ntsf_history_clear(h)
    type(ntsf_history), intent(inout) :: h
    if (c_associated(h%history)) call c_history_clear(h%history)
  end subroutine ntsf_history_clear

  ! The anchors of scene s's last evaluation become the history
  ! (nts_history_commit): that evaluation is the step the solver accepts.
  ! Give it the history (history=) and friction on (options%friction > 0 or
  ! a body's own); an evaluation without friction has no anchors, and
  ! committing it empties the history. status NTS_OK, NTS_ENOMEM (the
  ! history then unchanged), or NTS_EINVALID_ARGUMENT: no history, or no
  ! successful evaluation of s since it was created or last failed.
  subroutine ntsf_history_commit(h, s, status, err)
    type(ntsf_history), intent(inout) :: h
    type(ntsf_scene), intent(in) :: s
    integer, intent(out) :: status
    type(nts_error), intent(out), optional :: err
    type(nts_error) :: e
    e = no_error()
    if (.not. c_associated(h%history)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no history (ntsf_history_create first)")
    else if (.not. associated(s%last)) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no scene (ntsf_scene_create first)")
    else if (.not. s%last%ok) then
      status = fail(e, NTS_EINVALID_ARGUMENT, -1, "no evaluation to commit (the scene's last one failed, or none)")
    else
      status = c_history_commit(h%history, s%last%r)
      if (status /= NTS_OK) status = fail(e, int(status, c_int), -1, ntsf_strerror(status)//" (the history's commit)")
    end if
    if (present(err)) err = e
  end subroutine ntsf_history_commit

  ! How many anchors (stuck contacts) the history holds (0 for an empty handle).
  pure integer function ntsf_history_count(h)
    type(ntsf_history), intent(in) :: h
    ntsf_history_count = c_history_count(h%history)
  end function ntsf_history_count

  ! ------------------------------------------------------------- messages

  ! Short human message of a status ("zero-length segment"). Pure, as the
  ! other text functions: gfortran may then leave out a call in a condition
  ! that is already decided (-Wfunction-elimination warns about impure ones).
  pure function ntsf_strerror(status) result(text)
    integer, intent(in) :: status
    character(len=:), allocatable :: text
    text = c_string(c_strerror(int(status, c_int)))
  end function ntsf_strerror

  ! Stable snake_case name of a status ("degenerate_segment"), as the JSON
  ! documents and the CLI spell it.
  pure function ntsf_status_name(status) result(text)
    integer, intent(in) :: status
    character(len=:), allocatable :: text
    text = c_string(c_status_name(int(status, c_int)))
  end function ntsf_status_name

  pure function ntsf_warning_name(code) result(text)
    integer, intent(in) :: code
    character(len=:), allocatable :: text
    text = c_string(c_warning_name(int(code, c_int)))
  end function ntsf_warning_name

  ! The error record's own message: what is wrong where, with the C
  ! library's 0-based body, loop and node numbers ("body 1 loop 0: segment
  ! from node 3 to node 4 has length 0 ...").
  pure function ntsf_error_message(err) result(text)
    type(nts_error), intent(in) :: err
    character(len=:), allocatable :: text
    integer :: i, n
    n = 0
    do i = 1, size(err%message)
      if (err%message(i) == c_null_char) exit
      n = i
    end do
    allocate (character(len=n) :: text)
    do i = 1, n
      text(i:i) = err%message(i)
    end do
  end function ntsf_error_message

  ! .true. when every bind(C) type of this module has the size of its C
  ! struct (and the enums theirs), as this Fortran compiler and the C
  ! compiler that built the library lay them out; otherwise .false., and
  ! `detail` names the first that differs. ntsf_scene_create asks first.
  logical function ntsf_layout_ok(detail)
    character(len=:), allocatable, intent(out), optional :: detail
    character(len=*), parameter :: layout_names(16) = [character(len=19) :: &
      "nts_vec2", "nts_virial", "nts_error", "nts_limits", "nts_summary", "nts_options", &
      "nts_body_def", "nts_scene_def", "nts_triplets", "nts_warning", "nts_result", "nts_csr", &
      "nts_role", "nts_solver", "nts_candidates_info", "nts_contact"]
    integer(c_size_t) :: here(size(layout_names)), there
    type(nts_vec2) :: v
    type(nts_virial) :: vi
    type(nts_error) :: e
    type(nts_limits) :: l
    type(nts_summary) :: su
    type(nts_options) :: o
    type(nts_body_def) :: bd
    type(nts_scene_def) :: sd
    type(nts_triplets) :: t
    type(nts_warning) :: w
    type(nts_result) :: r
    type(nts_csr) :: c
    type(nts_candidates_info) :: ci
    type(nts_contact) :: ct
    integer(c_int) :: en
    integer :: k

    here = [c_sizeof(v), c_sizeof(vi), c_sizeof(e), c_sizeof(l), c_sizeof(su), c_sizeof(o), c_sizeof(bd), &
            c_sizeof(sd), c_sizeof(t), c_sizeof(w), c_sizeof(r), c_sizeof(c), c_sizeof(en), c_sizeof(en), &
            c_sizeof(ci), c_sizeof(ct)]
    ntsf_layout_ok = .true.
    if (present(detail)) detail = ""
    do k = 1, size(here)
      there = c_layout_sizeof(int(k - 1, c_int))
      if (here(k) /= there) then
        ntsf_layout_ok = .false.
        if (present(detail)) detail = trim(layout_names(k))//" is "//itoa(int(here(k), c_long_long))// &
          " bytes in Fortran, "//itoa(int(there, c_long_long))//" in C"
        return
      end if
    end do
  end function ntsf_layout_ok

  ! ------------------------------------------------------------ internals

  ! One body's nts_body_def: pointers into the caller's nodes and reference
  ! (C only reads them, during nts_scene_create) and into 0-based copies of
  ! its index arrays in `w`.
  integer function body_def_of(body, index, w, def, e) result(status)
    type(ntsf_body), intent(in), target :: body
    integer, intent(in) :: index
    type(body_indices), intent(inout), target :: w
    type(nts_body_def), intent(out) :: def
    type(nts_error), intent(inout) :: e
    integer :: n

    def%nodes = c_null_ptr
    def%node_count = 0
    def%loop_nodes = c_null_ptr
    def%loop_start = c_null_ptr
    def%loop_count = 0
    def%triangles = c_null_ptr
    def%triangle_count = 0
    def%role = body%role
    def%has_alpha = merge(1_c_int, 0_c_int, body%has_alpha)
    def%alpha = body%alpha
    def%reference = c_null_ptr
    def%surface = c_null_ptr
    def%surface_count = 0
    def%has_friction = merge(1_c_int, 0_c_int, body%has_friction)
    def%friction = body%friction
    def%self_contact = merge(1_c_int, 0_c_int, body%self_contact)
    status = NTS_OK

    n = 0
    if (allocated(body%nodes)) then
      if (size(body%nodes, 1) /= 2) then
        status = fail(e, NTS_EINVALID_ARGUMENT, index, "nodes must be shaped (2, node_count)")
        return
      end if
      n = size(body%nodes, 2)
      def%node_count = int(n, c_int)
      if (n > 0) def%nodes = c_loc(body%nodes(1, 1))
    end if

    if (allocated(body%triangles)) then
      if (size(body%triangles, 1) /= 3) then
        status = fail(e, NTS_EINVALID_ARGUMENT, index, "triangles must be shaped (3, triangle_count)")
        return
      end if
      if (size(body%triangles) > 0) then
        w%triangles = reshape(body%triangles, [size(body%triangles)]) - 1_c_int
        def%triangles = c_loc(w%triangles(1))
        def%triangle_count = int(size(body%triangles, 2), c_int)
      end if
    end if

    if (allocated(body%loop_nodes)) then
      if (size(body%loop_nodes) > 0) then
        w%loop_nodes = body%loop_nodes - 1_c_int
        if (allocated(body%loop_start)) then
          if (size(body%loop_start) < 2) then
            status = fail(e, NTS_EINVALID_ARGUMENT, index, "loop_start must have loop_count + 1 entries")
            return
          end if
          ! the loops are loop_nodes, one after another: loop_start runs from 1 to
          ! size(loop_nodes) + 1 and never decreases (the C side cannot see the
          ! array's end: an offset past it was read out of bounds)
          if (body%loop_start(1) /= 1 .or. body%loop_start(size(body%loop_start)) /= size(body%loop_nodes) + 1 &
              .or. any(body%loop_start(2:) < body%loop_start(:size(body%loop_start) - 1))) then
            status = fail(e, NTS_EINVALID_ARGUMENT, index, &
                          "loop_start must run from 1 to size(loop_nodes) + 1 and never decrease")
            return
          end if
          w%loop_start = body%loop_start - 1_c_int
        else
          w%loop_start = [0_c_int, int(size(body%loop_nodes), c_int)]
        end if
        def%loop_nodes = c_loc(w%loop_nodes(1))
        def%loop_start = c_loc(w%loop_start(1))
        def%loop_count = int(size(w%loop_start) - 1, c_int)
      end if
    end if

    if (allocated(body%surface)) then
      if (size(body%surface, 1) /= 2) then
        status = fail(e, NTS_EINVALID_ARGUMENT, index, "surface must be shaped (2, pair_count)")
        return
      end if
      if (size(body%surface) > 0) then
        w%surface = reshape(body%surface, [size(body%surface)]) - 1_c_int
      else
        ! No pairs is "no surface" in C only through a non-NULL pointer.
        w%surface = [-1_c_int]
      end if
      def%surface = c_loc(w%surface(1))
      def%surface_count = int(size(body%surface, 2), c_int)
    end if

    if (allocated(body%reference)) then
      if (size(body%reference, 1) /= 2 .or. size(body%reference, 2) /= n) then
        status = fail(e, NTS_EINVALID_ARGUMENT, index, "reference must be shaped (2, node_count) as nodes")
        return
      end if
      if (n > 0) def%reference = c_loc(body%reference(1, 1))
    end if
  end function body_def_of

  ! The C tangent's triplets as 1-based CSR, through nts_triplets_to_csr
  ! (duplicates summed in triplet order, columns sorted).
  integer function csr_of(t, m, e) result(status)
    type(nts_triplets), intent(in) :: t
    type(ntsf_csr), intent(inout) :: m
    type(nts_error), intent(inout) :: e
    type(nts_csr) :: c
    integer(c_int), pointer :: starts(:), cols(:)
    real(c_double), pointer :: vals(:)

    status = c_triplets_to_csr(t, c, e)
    if (status /= NTS_OK) return
    m%n = c%size
    call c_f_pointer(c%row_start, starts, [c%size + 1])
    m%row_ptr = starts + 1_c_int
    if (c%nnz > 0) then
      call c_f_pointer(c%cols, cols, [c%nnz])
      call c_f_pointer(c%values, vals, [c%nnz])
      m%col = cols + 1_c_int
      m%val = vals
    else
      m%col = [integer(c_int) ::]
      m%val = [real(c_double) ::]
    end if
    call c_csr_free(c)
  end function csr_of

  subroutine clear_csr(m)
    type(ntsf_csr), intent(inout) :: m
    m%n = 0
    if (allocated(m%row_ptr)) deallocate (m%row_ptr)
    if (allocated(m%col)) deallocate (m%col)
    if (allocated(m%val)) deallocate (m%val)
  end subroutine clear_csr

  ! The C result's `count` records at p as ntsf_contact, 1-based (asked:
  ! the output was asked for; else `to` is deallocated). Kept allocated
  ! between evaluations while the count does not change.
  subroutine contacts_of(p, count, asked, to)
    type(c_ptr), intent(in) :: p
    integer(c_int), intent(in) :: count
    logical, intent(in) :: asked
    type(ntsf_contact), allocatable, intent(inout) :: to(:)
    type(nts_contact), pointer :: c(:)
    integer :: k
    if (allocated(to)) then
      if (.not. asked .or. size(to) /= count) deallocate (to)
    end if
    if (.not. asked) return
    if (.not. allocated(to)) allocate (to(count))
    if (count == 0) return
    call c_f_pointer(p, c, [count])
    do k = 1, count
      to(k)%slave_body = c(k)%slave_body + 1
      to(k)%slave_node = c(k)%slave_node + 1
      to(k)%master_body = c(k)%master_body + 1
      to(k)%kind = c(k)%kind
      to(k)%master_count = c(k)%master_count
      to(k)%master_nodes = c(k)%master_nodes + 1 ! C's -1 past master_count: 0
      to(k)%weights = c(k)%weights
      to(k)%param = c(k)%param
      to(k)%gap = c(k)%gap
      to(k)%normal = [c(k)%normal%x, c(k)%normal%y]
      to(k)%point = [c(k)%point%x, c(k)%point%y]
      to(k)%force = [c(k)%force%x, c(k)%force%y]
      to(k)%virial = [c(k)%virial%xx, c(k)%virial%yy, c(k)%virial%xy, c(k)%virial%yx]
      to(k)%penalty = c(k)%penalty
      to(k)%tangential_force = [c(k)%tangential_force%x, c(k)%tangential_force%y]
      to(k)%slip = c(k)%slip
      to(k)%state = c(k)%state
    end do
  end subroutine contacts_of

  subroutine clear_output(out)
    type(ntsf_output), intent(inout) :: out
    out%summary = nts_summary(0, 0, 0, 0, 0, 0.0_c_double, nts_virial(0.0_c_double, 0.0_c_double, 0.0_c_double, &
      0.0_c_double), 0.0_c_double, 0, 0.0_c_double, 0.0_c_double, 0.0_c_double, 0, 0)
    if (allocated(out%forces)) deallocate (out%forces)
    if (allocated(out%pressure)) deallocate (out%pressure)
    if (allocated(out%warning_codes)) deallocate (out%warning_codes)
    if (allocated(out%warning_counts)) deallocate (out%warning_counts)
    if (allocated(out%contacts)) deallocate (out%contacts)
    if (allocated(out%gaps)) deallocate (out%gaps)
    call clear_csr(out%tangent)
  end subroutine clear_output

  ! nts_error_none(): code 0, every index -1, no text.
  function no_error() result(e)
    type(nts_error) :: e
    e%code = NTS_OK
    e%body = -1
    e%loop = -1
    e%loop_pos = -1
    e%node = -1
    e%triangle = -1
    e%corner = -1
    e%item = -1
    e%option = c_null_char
    e%message = c_null_char
  end function no_error

  ! An error found on this side of the border, recorded as C records its own
  ! (the body 0-based, as in the C library's messages).
  integer function fail(e, code, body, text) result(status)
    type(nts_error), intent(inout) :: e
    integer(c_int), intent(in) :: code
    integer, intent(in) :: body
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: full
    integer :: i, n
    e = no_error()
    e%code = code
    e%body = int(body, c_int)
    if (body >= 0) then
      full = "body "//itoa(int(body, c_long_long))//": "//text
    else
      full = text
    end if
    n = min(len(full), size(e%message) - 1)
    do i = 1, n
      e%message(i) = full(i:i)
    end do
    status = code
  end function fail

  ! An integer as text. The module does no formatted I/O of its own: a
  ! library has no business with the program's units, and libgfortran
  ! copies a format with strndup, which AddressSanitizer's
  ! strict_string_checks (scripts/test-sanitize.sh) reads past a Fortran
  ! string that has no NUL after it.
  pure function itoa(i) result(text)
    integer(c_long_long), intent(in) :: i
    character(len=:), allocatable :: text
    character(len=20) :: buf
    integer(c_long_long) :: v
    integer :: p
    v = abs(i)
    p = len(buf) + 1
    do
      p = p - 1
      buf(p:p) = achar(iachar("0") + int(mod(v, 10_c_long_long)))
      v = v / 10
      if (v == 0) exit
    end do
    if (i < 0) then
      p = p - 1
      buf(p:p) = "-"
    end if
    text = buf(p:)
  end function itoa

  ! A NUL-terminated C string (static in the library) as a Fortran one.
  pure function c_string(p) result(text)
    type(c_ptr), intent(in) :: p
    character(len=:), allocatable :: text
    integer(c_size_t) :: n
    if (.not. c_associated(p)) then
      text = ""
      return
    end if
    n = c_strlen(p)
    allocate (character(len=n) :: text)
    if (n > 0) call c_copy_string(text, p, n)
  end function c_string

end module ntscontact

! Two pressed squares through the Fortran module: the scene from arrays, an
! evaluation with the tangent, a step of moved positions, a solver's loop
! with a kept candidate list and friction, an error.
program squares
  use, intrinsic :: iso_c_binding, only: dp => c_double
  use ntscontact
  implicit none
  type(ntsf_body) :: bodies(2)
  type(ntsf_scene) :: scene
  type(ntsf_output) :: out
  type(nts_options) :: opt
  type(nts_error) :: err
  type(ntsf_candidates) :: kc
  type(ntsf_history) :: h
  type(nts_candidates_info) :: info
  real(dp), allocatable :: x(:, :)
  integer :: status, step

  ! Nodes (2, n), counter-clockwise; no loops given: the nodes are one loop.
  bodies(1)%nodes = reshape([0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 1.0_dp, 1.0_dp, 0.0_dp, 1.0_dp], [2, 4])
  bodies(2)%nodes = reshape([0.95_dp, 0.1_dp, 2.0_dp, 0.1_dp, 2.0_dp, 1.1_dp, 0.95_dp, 1.1_dp], [2, 4])
  call ntsf_scene_create(scene, bodies, status, err=err)
  if (status /= NTS_OK) then
    print '(3a)', ntsf_status_name(status), ": ", ntsf_error_message(err)
    error stop 1
  end if

  opt = nts_default_options()
  opt%penalty = 100
  opt%search_radius = 0.2_dp
  opt%outputs = ior(ior(NTS_OUT_FORCES, NTS_OUT_ENERGY), ior(NTS_OUT_VIRIAL, NTS_OUT_STIFFNESS))
  call ntsf_evaluate(scene, opt, out, status, err)
  if (status /= NTS_OK) error stop 1
  print '(a, i0, a, es12.5, a, es12.5)', "contacts ", out%summary%contacts, ", energy ", out%summary%energy, &
    ", virial xx ", out%summary%virial%xx
  print '(a, 2es13.5)', "force on node 2 (1, 0):", out%forces(:, 2)
  print '(a, i0, a, i0, a, i0, a)', "tangent ", out%tangent%n, " x ", out%tangent%n, ", ", size(out%tangent%val), " entries"

  ! A step: the right square 0.01 further in, the same scene at new positions.
  x = reshape([bodies(1)%nodes, bodies(2)%nodes], [2, 8])
  x(1, 5:8) = x(1, 5:8) - 0.01_dp
  call ntsf_evaluate(scene, opt, out, status, err, positions=x)
  if (status /= NTS_OK) error stop 1
  print '(a, es12.5)', "after the step: energy ", out%summary%energy

  ! A solver's loop: a kept candidate list (the same answers, in less time
  ! while the nodes move a little) and friction with its history. Each
  ! evaluation is a trial from the committed history; an implicit solver
  ! commits its converged iterate, this loop every step.
  call ntsf_candidates_create(kc, status)
  call ntsf_history_create(h, status)
  opt%friction = 0.3_dp
  do step = 1, 5
    x(2, 5:8) = x(2, 5:8) + 0.002_dp ! the right square slides up
    call ntsf_evaluate(scene, opt, out, status, err, positions=x, candidates=kc, history=h)
    if (status /= NTS_OK) error stop 1
    call ntsf_history_commit(h, scene, status)
  end do
  info = ntsf_candidates_info(kc)
  print '(a, i0, a, i0, a, i0, a, 2es13.5)', "5 sliding steps: ", info%evaluations, " evaluations, ", info%builds, &
    " build, ", ntsf_history_count(h), " anchors, force on node 2:", out%forces(:, 2)
  call ntsf_history_destroy(h)
  call ntsf_candidates_destroy(kc)

  ! Errors come back as a status and a message (the node numbers 0-based, as C's).
  x(:, 6) = x(:, 5)
  call ntsf_update_positions(scene, x, status, err)
  print '(a, i0, 4a)', "status ", status, " ", ntsf_status_name(status), ": ", ntsf_error_message(err)
  call ntsf_scene_destroy(scene)
end program squares

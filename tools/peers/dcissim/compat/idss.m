function sys = idss(A, B, C, D, Ts)
% sys = idss(A, B, C, D [, Ts]): what the authors' code needs of MATLAB's identified state-space
% model, a struct holding the matrices and the sample time (discrete, Ts = 1 by default as MATLAB's
% idss). A stand-in for Octave (msid's own code).
  if nargin < 5
    Ts = 1;
  end
  sys = struct('A', A, 'B', B, 'C', C, 'D', D, 'Ts', Ts);
end

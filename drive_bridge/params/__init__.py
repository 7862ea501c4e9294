"""Drive parameters: profiles that map abstract parameters to objects, and the transactional write."""

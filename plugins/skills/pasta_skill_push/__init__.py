"""Built-in skill plugin 'push': push one dough piece to a new place with the pusher."""
